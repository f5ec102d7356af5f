"""The fleet engine: one mission, many vehicles, Dolphin's orchestration operators.

Theory of operation
-------------------
Like the single-vehicle :class:`~tml.engine.Interpreter`, the fleet is pure: each
:meth:`Fleet.step` takes the time, every vehicle's latest state and the results of its
requests, and returns the requests to send (each addressed to its vehicle by
``vehicle_id``) and the records to log. It never sleeps or reads a clock, so every
composition is tested with fake vehicles and an injected clock.

*Branches.* The task tree is run by a tree of Python generators, one per running task:
a generator does one step of its task's work and yields until the next
:meth:`~Fleet.step`. A ``sequence`` runs its children's generators one after the other,
``parallel`` and ``first`` advance all of theirs on every step, ``choice`` waits for a
child whose conditions hold. Stopping a branch (``until``, ``time_limit``, the end of a
``first`` sibling, a sibling's failure, the end of the mission) closes its generator: the
``finally`` blocks stop what runs below it, so nothing is left running unseen. A failure
is an exception (:class:`_Failure`) that climbs the tree to the nearest ``on_error``;
END_MISSION and ABORT_MISSION climb to the top as :class:`_MissionEnd`.

*Vehicle work.* A task that uses no orchestration operator, nor do its sub-tasks, and is
flown by one role is a *segment*: an :class:`~tml.engine.Interpreter` runs it on the
vehicle, with the mission's event handlers for that role, exactly as a whole mission runs
on one vehicle (conditions, repeat, skills, actions, ``dispatch="mission"``, events).
Memorized points and speed limits belong to the vehicle and carry over from one segment
to the next. A mission without roles and without orchestration is one segment: the
interpreter as it always was.

*Roles.* A role is picked when the first task flown by it starts and it is not bound:
the free vehicles that qualify (type, payloads, region, live link) are taken in the
order of how long they have been free (the longest first, never-used vehicles since the
run began), ties by vehicle id; the pick waits up to the role's ``pick_timeout`` and then
fails the task with every vehicle's reason. ``release`` frees a role's vehicles when its
task ends; a freed vehicle in the air is sent to the safe state. A role of ``count`` N
flies each of its tasks on all N vehicles, one branch each.

*Safety.* When the mission ends, however it ends, every bound vehicle that is flying is
commanded to the safe state (RTL by default), and an armed one on the ground is disarmed.
"""

from __future__ import annotations

import math
from collections.abc import Generator, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace

from tml.engine.conditions import Memory, evaluate, evaluate_all
from tml.engine.interpreter import (
    Interpreter,
    Options,
    Output,
    Record,
    Status,
    TaskState,
    View,
    request_fields,
    safe_state_request,
)
from tml.engine.scripts import Limits
from tml.language.kinds import vehicle_type_matches
from tml.language.model import Composition, Condition, Event, Mission, Role, Task
from tml.vehicle import (
    Hold,
    Point,
    Request,
    RequestResult,
    SetSkill,
    VehicleState,
)

# A branch's roles and the one vehicle each stands for in it (None: the mission has no
# roles and the fleet flies it on one vehicle).
Context = Mapping[str | None, int]
Step = Generator[None, None, None]


class _Failure(Exception):
    """A task failed; climbs to the nearest on_error."""

    def __init__(self, reason: str, detail: str, status: Status = Status.FAILED) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason, self.detail, self.status = reason, detail, status


class _MissionEnd(Exception):
    """END_MISSION or ABORT_MISSION fired on a vehicle: the whole mission ends."""

    def __init__(self, status: Status, reason: str) -> None:
        super().__init__(reason)
        self.status, self.reason = status, reason


@dataclass
class _Vehicle:
    """What the fleet keeps of one vehicle across segments."""

    vehicle_id: int
    payloads: frozenset[str]
    state: VehicleState
    free_since: float = -math.inf  # never used: free since before the run
    role: str | None = None
    lost: str = ""  # why the vehicle cannot be used any more
    labels: dict[str, Point] = field(default_factory=dict)
    limits: Limits | None = None
    last_target: Point | None = None
    segment: Interpreter | None = None
    results: list[RequestResult] = field(default_factory=list)


class Fleet:
    """Runs one mission on a fleet of vehicles; see the module docstring.

    ``vehicles`` are the connected vehicle ids in pick order of preference (ties);
    ``payloads`` what each carries beyond what its state reports.
    """

    def __init__(self, mission: Mission, vehicles: Sequence[int],
                 options: Options | None = None,
                 payloads: Mapping[int, Iterable[str]] | None = None) -> None:
        self.mission = mission
        self.options = options or Options()
        self.status = Status.RUNNING
        self.reason = ""
        self._vehicles = {vid: _Vehicle(vid, frozenset(p.lower() for p in
                                                       (payloads or {}).get(vid, ())),
                                        VehicleState(vid, 0.0))
                          for vid in vehicles}
        self._bound: dict[str | None, tuple[int, ...]] = {}
        self._states: dict[str, TaskState] = {t.path_name: TaskState.PENDING
                                              for t in mission.walk()}
        # What each vehicle flew, and the tasks no vehicle flies (pure orchestration), for
        # the per-vehicle views.
        self._flown: dict[int | None, dict[str, TaskState]] = {None: {}}
        self._started: dict[tuple[str, ...], float] = {}
        self._events: list[tuple[float, str]] = []
        self._classic = not mission.roles and not any(
            t.orchestrated for t in mission.walk())
        self._now = 0.0
        self._start = 0.0
        self._out = Output()
        self._root: Step | None = None
        self._why = ""  # why branches are being stopped, for their records
        self._ending = False

    # --- the public API ----------------------------------------------------------------------

    @property
    def vehicle_ids(self) -> list[int]:
        """The fleet's vehicles."""
        return list(self._vehicles)

    def start(self, now: float, states: Mapping[int, VehicleState]) -> Output:
        """Begin the mission."""
        self._begin(now, states, {})
        self._start = now
        if not self._classic:  # else the interpreter says it
            self._note("mission", f"mission {self.mission.name!r} started",
                       name=self.mission.name, vehicles=list(self._vehicles),
                       roles=[r.name for r in self.mission.roles])
        if not self.mission.roles:
            # Without roles the fleet has one vehicle and every task is its own.
            self._bound[None] = tuple(self._vehicles)
        self._root = self._mission()
        self._advance()
        return self._finish()

    def step(self, now: float, states: Mapping[int, VehicleState],
             results: Mapping[int, Sequence[RequestResult]] | None = None) -> Output:
        """Take the time, the latest states and request results; return what to do."""
        self._begin(now, states, results or {})
        if self.status is Status.RUNNING:
            self._advance()
        return self._finish()

    def lost(self, now: float, vehicle_id: int, reason: str) -> Output:
        """A vehicle cannot be used any more (its link is lost): the task it flies fails,
        and it is never picked again."""
        self._now = now
        vehicle = self._vehicles[vehicle_id]
        vehicle.lost = reason
        role = vehicle.role
        if role is not None:
            # The role lets go of it: the role's next task (an on_error) picks another.
            rest = tuple(v for v in self._bound.get(role, ()) if v != vehicle_id)
            if rest:
                self._bound[role] = rest
            else:
                self._bound.pop(role, None)
            vehicle.role = None
        self._note("vehicle", f"vehicle {vehicle_id}: {reason}", vehicle=vehicle_id,
                   reason=reason)
        if self.status is Status.RUNNING:
            self._advance()  # its task fails (and is stopped) now
        if role is not None:
            # Nobody flies it any more; if the link comes back, it goes to the safe state.
            self._safe_state(vehicle, reason)
        return self._finish()

    def abort(self, now: float, states: Mapping[int, VehicleState], reason: str) -> Output:
        """Stop everything and command the safe state (interpreter error, Ctrl-C)."""
        self._begin(now, states, {})
        if self.status is Status.RUNNING:
            self._end(Status.ABORTED, reason)
        return self._finish()

    def views(self) -> dict[int, View]:
        """A snapshot per vehicle for the display."""
        views = {}
        for vid, vehicle in self._vehicles.items():
            segment = vehicle.segment.view() if vehicle.segment is not None else None
            states = {**self._flown[None], **self._flown.get(vid, {})}
            if segment is not None:
                states.update({path: state for path, state in segment.task_states.items()
                               if state is not TaskState.PENDING})
            role = vehicle.role if vehicle.role is not None else ""
            views[vid] = View(
                self.status, states, segment.current_task if segment else "",
                segment.current_action if segment else "",
                segment.progress if segment else None, dict(vehicle.labels),
                tuple(self._events), self._now - self._start,
                self.reason or (vehicle.lost if vehicle.lost else ""), role)
        return views

    def role_states(self, role: str) -> list[VehicleState]:
        """The latest states of a role's vehicles (empty when it is not picked)."""
        return [self._vehicles[v].state for v in self._bound.get(role, ())]

    # --- plumbing ------------------------------------------------------------------------------

    def _begin(self, now: float, states: Mapping[int, VehicleState],
               results: Mapping[int, Sequence[RequestResult]]) -> None:
        self._now = now
        for vid, state in states.items():
            if vid in self._vehicles:
                self._vehicles[vid].state = state
        for vid, found in results.items():
            if vid in self._vehicles:
                self._vehicles[vid].results.extend(found)

    def _finish(self) -> Output:
        for vehicle in self._vehicles.values():
            if vehicle.segment is None and vehicle.results:
                for result in vehicle.results:  # answers to holds and releases
                    if not result.ok:
                        self._note("result", f"request {result.request_id} failed: "
                                   f"{result.reason}", vehicle.vehicle_id,
                                   request_id=result.request_id, ok=False,
                                   reason=result.reason, detail=result.detail)
                vehicle.results.clear()
        out, self._out = self._out, Output()
        return out

    def _note(self, kind: str, message: str, vehicle: int | None = None, /,
              **data: object) -> None:
        self._out.records.append(Record(self._now, kind, {"message": message, **data},
                                        vehicle))

    def _send(self, request: Request) -> None:
        self._out.requests.append(request)
        self._note("request", request.name, request.vehicle_id,
                   request_id=request.request_id, **request_fields(request))

    def _take(self, vid: int, output: Output) -> None:
        """A segment's output, its records marked with its vehicle."""
        for record in output.records:
            kind, data = record.kind, record.data
            if kind == "mission" and not self._classic:
                # A segment is one vehicle's part of the mission, not the mission.
                kind = "branch"
                data = {**data, "message": str(data["message"]).replace(
                    "mission aborted", "branch stopped").replace("mission ", "branch ", 1)}
            if kind == "event":
                self._events.append((record.time - self._start, str(data["event"])))
            self._out.records.append(Record(record.time, kind, data, vid))
        self._out.requests.extend(output.requests)

    def _set(self, task: Task, state: TaskState, vid: int | None = None) -> None:
        self._states[task.path_name] = state
        self._flown.setdefault(vid, {})[task.path_name] = state
        self._note("task", f"{task.path_name}: {state.value}", vid, task=task.path_name,
                   state=state.value)

    def _advance(self) -> None:
        root = self._root
        if root is None:
            return
        try:
            next(root)
        except StopIteration:
            self._end(Status.COMPLETED, "all tasks done")
        except _MissionEnd as end:
            self._end(end.status, end.reason)
        except _Failure as failure:
            # An action's failure is said by its interpreter already in full.
            self._end(failure.status, failure.detail if failure.reason == "action"
                      else f"{failure.reason}: {failure.detail}")

    def _end(self, status: Status, reason: str) -> None:
        self.status, self.reason = status, reason
        root, self._root = self._root, None
        self._ending = True
        if root is not None:
            self._close(root, reason)
        for states in (self._states, *self._flown.values()):
            for path, state in states.items():
                if state is TaskState.RUNNING:
                    states[path] = (TaskState.DONE if status is Status.COMPLETED
                                    else TaskState.ABORTED)
        if self._classic:
            return  # the interpreter has said it, and put the vehicle in the safe state
        self._note("mission", f"mission {status.value}: {reason}", status=status.value,
                   reason=reason)
        for role in list(self._bound):
            self._release(role, reason)

    def _close(self, branch: Step, why: str) -> None:
        """Stop a branch; what runs in it is stopped for ``why``."""
        outer, self._why = self._why, why
        try:
            branch.close()
        finally:
            self._why = outer

    # --- the mission and its tasks -----------------------------------------------------------

    def _mission(self) -> Step:
        if self._classic:
            vid = next(iter(self._vehicles))
            yield from self._segment(self.mission, vid, {None: vid}, end_safe=True)
            return
        for vid in self._bound.get(None, ()):
            for skill in self.mission.skills:
                self._send(SetSkill(vid, skill.name, True))
        yield from self._sequence(self.mission.tasks, {})

    def _sequence(self, tasks: Sequence[Task], ctx: Context) -> Step:
        for task in tasks:
            yield from self._task(task, ctx)

    def _task(self, task: Task, ctx: Context) -> Step:
        role = task.role
        needs_vehicle = role is not None or task.is_terminal or None in self._bound
        try:
            # A role released since this branch bound it (a loop round that ends with
            # release) is picked again, as on first use.
            if needs_vehicle and ctx.get(role) not in self._bound.get(role, ()):
                vids = self._bound.get(role)
                if not vids:
                    try:
                        vids = yield from self._pick(task, role)
                    except _Failure as failure:
                        self._set(task, TaskState.FAILED)
                        if not task.on_error:
                            raise
                        yield from self._recover(task, ctx, None, failure)
                        return
                if len(vids) > 1:  # a team: every vehicle flies the task
                    yield from self._together([self._fly(task, {**ctx, role: v})
                                               for v in vids])
                    return
                ctx = {**ctx, role: vids[0]}
            yield from self._fly(task, ctx)
        finally:  # once, when every vehicle of a team is done with the task
            for name in task.release:
                self._release(name, f"released by {task.path_name}")

    def _fly(self, task: Task, ctx: Context) -> Step:
        """The task on the vehicle ``ctx`` gives its role."""
        vid = ctx.get(task.role)
        if self._plain(task):
            yield from self._segment(self._alone(task), vid, ctx)  # type: ignore[arg-type]
        else:
            yield from self._orchestrated(task, ctx, vid)

    def _recover(self, task: Task, ctx: Context, vid: int | None, failure: _Failure) -> Step:
        """The task failed: its on_error tasks run in sequence, with the same role."""
        self._note("decision", f"{task.path_name}: failed ({failure.reason}: "
                   f"{failure.detail}); its on_error tasks run", vid,
                   task=task.path_name, reason=failure.reason, detail=failure.detail)
        yield from self._sequence(task.on_error, ctx)

    def _orchestrated(self, task: Task, ctx: Context, vid: int | None) -> Step:
        if task.wait_for:
            self._note("decision", f"{task.path_name}: waiting for its conditions", vid,
                       task=task.path_name)
            while not self._holds(task.wait_for, ctx, task):
                yield
        if not self._holds(task.conditions, ctx, task, log=True):
            self._set(task, TaskState.SKIPPED, vid)
            return
        self._started[task.path] = self._now
        self._set(task, TaskState.RUNNING, vid)
        skills = [s.name for s in task.skills] if vid is not None else []
        for name in skills:
            self._send(SetSkill(vid, name, True))  # type: ignore[arg-type]
        body = self._rounds(task, ctx)
        if task.until or task.time_limit is not None:
            body = self._bounded(task, ctx, body, vid)
        try:
            if task.on_error:
                try:
                    yield from body
                except _Failure as failure:
                    self._set(task, TaskState.FAILED, vid)
                    yield from self._recover(task, ctx, vid, failure)
                    return
            else:
                yield from body
            self._set(task, TaskState.DONE, vid)
        except _Failure:
            self._set(task, TaskState.FAILED, vid)
            raise
        except GeneratorExit:
            self._set(task, TaskState.ABORTED, vid)
            raise
        finally:
            for name in skills:
                self._send(SetSkill(vid, name, False))  # type: ignore[arg-type]

    def _rounds(self, task: Task, ctx: Context) -> Step:
        """The task's body, ``repeat`` times or as long as its loop says."""
        round_number = 0
        while True:
            round_number += 1
            if task.loop is not None:
                if not self._holds(task.loop.conditions, ctx, task):
                    self._note("decision", f"{task.path_name}: loop ends after "
                               f"{round_number - 1} rounds", ctx.get(task.role),
                               task=task.path_name, rounds=round_number - 1)
                    return
            elif round_number > task.repeat:
                return
            if round_number > 1:
                self._note("decision", f"{task.path_name}: round {round_number}",
                           ctx.get(task.role), task=task.path_name, round=round_number)
            if task.is_terminal:
                inner = replace(task, conditions=(), skills=(), repeat=1, wait_for=(),
                                until=(), time_limit=None, on_error=(), loop=None,
                                release=())
                yield from self._segment(self._alone(inner), ctx[task.role], ctx)
            elif task.composition is Composition.SEQUENCE:
                yield from self._sequence(task.children, ctx)
            elif task.composition is Composition.CHOICE:
                yield from self._choice(task, ctx)
            else:
                yield from self._together([self._task(c, ctx) for c in task.children],
                                          first=task.composition is Composition.FIRST)
            if task.loop is not None and not task.loop.conditions:
                yield  # a forever loop over instant work still lets time pass

    def _bounded(self, task: Task, ctx: Context, body: Step, vid: int | None) -> Step:
        """``body`` stopped (as done) once the task's until conditions hold or its time
        limit is reached."""
        started = self._now
        try:
            while True:
                why = ""
                if task.until and self._holds(task.until, ctx, task):
                    why = "its until conditions hold"
                elif task.time_limit is not None and self._now - started >= task.time_limit:
                    why = f"its time limit of {task.time_limit:g} s is reached"
                if why:
                    self._note("decision", f"{task.path_name}: stopped, {why}", vid,
                               task=task.path_name)
                    self._close(body, f"{task.path_name}: {why}")
                    return
                try:
                    next(body)
                except StopIteration:
                    return
                yield
        finally:
            body.close()  # when this branch is itself stopped from above

    def _together(self, branches: list[Step], first: bool = False) -> Step:
        """Advance every branch on every step; done when all are (or the first is)."""
        running = list(branches)
        try:
            while running:
                for branch in list(running):
                    try:
                        next(branch)
                    except StopIteration:
                        running.remove(branch)
                        if first:
                            for other in running:
                                self._close(other, "another branch finished first")
                            return
                if running:
                    yield
        except (_Failure, _MissionEnd):
            for branch in running:
                self._close(branch, "a sibling branch failed")
            raise
        finally:
            for branch in running:  # stopped from above: the reason is already set
                branch.close()

    def _choice(self, task: Task, ctx: Context) -> Step:
        while True:
            for child in task.children:
                if self._holds(child.conditions, {**ctx}, child):
                    for other in task.children:
                        if other is not child:
                            self._set(other, TaskState.SKIPPED)
                    self._note("decision", f"{task.path_name}: {child.name} chosen", None,
                               task=task.path_name, chosen=child.path_name)
                    yield from self._task(child, ctx)
                    return
            yield

    # --- segments ----------------------------------------------------------------------------

    def _plain(self, task: Task) -> bool:
        """Whether the task can be flown by one interpreter on one vehicle."""
        return all(not t.orchestrated and t.role == task.role for t in task.walk())

    def _alone(self, task: Task) -> Mission:
        """A mission holding just ``task`` and the event handlers of its role."""
        events = tuple(e for e in self.mission.events if _applies(e, task.role))
        return replace(self.mission, tasks=(task,), events=events, skills=(), roles=())

    def _segment(self, mission: Mission, vid: int, ctx: Context,
                 end_safe: bool = False) -> Step:
        vehicle = self._vehicles[vid]
        options = replace(self.options, end_safe=end_safe,
                          role_states=lambda role: self._states_in(role, ctx))
        interpreter = Interpreter(mission, vid, options)
        # What the vehicle learnt in earlier tasks (points, speed) it keeps.
        interpreter.labels = vehicle.labels
        if vehicle.limits is not None:
            interpreter.limits = vehicle.limits
        vehicle.limits = interpreter.limits
        interpreter.last_target = vehicle.last_target
        vehicle.segment = interpreter
        try:
            self._take(vid, interpreter.start(self._now, vehicle.state))
            while interpreter.status is Status.RUNNING:
                yield
                if vehicle.lost:
                    # The request may still get through if the link comes back.
                    end = interpreter.abort if end_safe else interpreter.stop
                    self._take(vid, end(self._now, vehicle.state, vehicle.lost))
                    raise _Failure("link", f"vehicle {vid}: {vehicle.lost}")
                results, vehicle.results = vehicle.results, []
                self._take(vid, interpreter.step(self._now, vehicle.state, results))
        except GeneratorExit:
            if interpreter.status is Status.RUNNING:
                why = self._why or "stopped"
                if end_safe:
                    self._take(vid, interpreter.abort(self._now, vehicle.state, why))
                else:
                    out = interpreter.stop(self._now, vehicle.state, why)
                    if self._ending:  # the fleet sends the safe state itself
                        out.requests = [r for r in out.requests if not isinstance(r, Hold)]
                    self._take(vid, out)
            raise
        finally:
            vehicle.last_target = interpreter.last_target
            vehicle.segment = None
            flown = {p: s for p, s in interpreter.view().task_states.items()
                     if s is not TaskState.PENDING}
            self._states.update(flown)
            self._flown.setdefault(vid, {}).update(flown)
        if interpreter.mission_end is not None:
            raise _MissionEnd(interpreter.mission_end, interpreter.reason)
        if interpreter.status is not Status.COMPLETED:
            raise _Failure("action", interpreter.reason, interpreter.status)

    # --- roles -------------------------------------------------------------------------------

    def _pick(self, task: Task, name: str | None) -> Generator[None, None, tuple[int, ...]]:
        role = self.mission.role(name) if name is not None else None
        if role is None:
            raise _Failure("pick", f"{task.path_name}: no vehicle for it (role {name!r} is "
                           "not declared)")
        since = self._now
        while True:
            chosen, refused = self._candidates(role)
            if len(chosen) >= role.count:
                picked = tuple(chosen[:role.count])
                self._bound[role.name] = picked
                for vid in picked:
                    self._vehicles[vid].role = role.name
                    for skill in self.mission.skills:
                        self._send(SetSkill(vid, skill.name, True))
                self._note("pick", f"role {role.name!r}: vehicle"
                           f"{'s' if len(picked) > 1 else ''} "
                           f"{', '.join(map(str, picked))} picked", None, role=role.name,
                           vehicles=list(picked), waited=round(self._now - since, 3))
                return picked
            if self._now - since >= role.pick_timeout:
                why = "; ".join(f"vehicle {vid}: {reason}" for vid, reason in refused)
                detail = (f"role {role.name!r} needs {role.count} vehicle"
                          f"{'s' if role.count > 1 else ''}, {len(chosen)} qualified within "
                          f"{role.pick_timeout:g} s" + (f" ({why})" if why else ""))
                self._note("pick", f"pick failed: {detail}", None, role=role.name,
                           refused=dict(refused))
                raise _Failure("pick", detail)
            yield

    def _candidates(self, role: Role) -> tuple[list[int], list[tuple[int, str]]]:
        """The vehicles that qualify for ``role``, best first, and why the others do not."""
        chosen: list[_Vehicle] = []
        refused: list[tuple[int, str]] = []
        for vehicle in self._vehicles.values():
            why = self._refusal(role, vehicle)
            if why:
                refused.append((vehicle.vehicle_id, why))
            else:
                chosen.append(vehicle)
        chosen.sort(key=lambda v: (v.free_since, v.vehicle_id))
        return [v.vehicle_id for v in chosen], refused

    def _refusal(self, role: Role, vehicle: _Vehicle) -> str:
        state = vehicle.state
        if vehicle.lost or state.link == "lost":
            return vehicle.lost or "link lost"
        if vehicle.role is not None:
            return f"busy (role {vehicle.role!r})"
        if role.vehicle_type and not vehicle_type_matches(role.vehicle_type,
                                                          state.vehicle_type):
            return f"a {state.vehicle_type or 'vehicle of unknown type'}, not " \
                   f"{role.vehicle_type}"
        carried = vehicle.payloads | {c.lower() for c in state.capabilities}
        missing = [p for p in role.payloads if p.lower() not in carried]
        if missing:
            return f"no {', '.join(missing)}"
        if role.region is not None:
            where = self._mission_frame(state)
            if where is None:
                return "position unknown"
            region = role.region
            if region.is_circle:
                inside = math.dist(where, region.points[0]) <= (region.radius or 0.0)
            else:
                import shapely  # here: it loads threading, which the pure engine avoids

                inside = shapely.Polygon(region.points).covers(shapely.Point(where))
            if not inside:
                return f"outside the region (at {where[0]:.0f} m N, {where[1]:.0f} m E)"
        return ""

    def _mission_frame(self, state: VehicleState) -> tuple[float, float] | None:
        """The vehicle's (north, east) from the mission's home."""
        if state.position is None:
            return None
        world = self.options.world or self.mission.world
        home = world.home if world is not None else None
        if home is None or state.home is None:
            return state.position[0], state.position[1]
        from tml import geo  # the frames differ only when both homes are known

        lat, lon, _ = geo.to_global(state.position, state.home)
        north, east, _ = geo.to_local(lat, lon, home.altitude, home.latitude,
                                      home.longitude, home.altitude)
        return north, east

    def _release(self, name: str | None, reason: str) -> None:
        vids = self._bound.pop(name, ())  # type: ignore[arg-type]
        for vid in vids:
            vehicle = self._vehicles[vid]
            vehicle.role = None
            vehicle.free_since = self._now
            if name is not None:
                self._note("release", f"role {name!r}: vehicle {vid} released ({reason})",
                           vid, role=name)
            for skill in self.mission.skills:
                self._send(SetSkill(vid, skill.name, False))
            self._safe_state(vehicle, reason)

    def _safe_state(self, vehicle: _Vehicle, reason: str) -> None:
        safe = safe_state_request(vehicle.state, self.options.safe_state)
        if safe is not None:
            request, why = safe
            self._note("safety", f"{why} ({reason})", vehicle.vehicle_id,
                       request=request.name)
            self._send(request)

    # --- conditions --------------------------------------------------------------------------

    def _states_in(self, role: str, ctx: Context) -> list[VehicleState]:
        if role in ctx:
            return [self._vehicles[ctx[role]].state]
        return self.role_states(role)

    def _holds(self, conditions: Sequence[Condition], ctx: Context, task: Task,
               log: bool = False) -> bool:
        vid = ctx.get(task.role)
        bound = self._bound.get(task.role, ())
        if vid is None and len(bound) == 1:
            vid = bound[0]
        vehicle = self._vehicles[vid] if vid is not None else None
        memory = Memory(vehicle.labels if vehicle else {}, self._now - self._start,
                        self._now - self._started.get(task.path, self._now), task.path, "",
                        None, frozenset(task.path[:i] for i in range(1, len(task.path) + 1)))
        for condition in conditions:
            if condition.role is not None:
                holds, value = evaluate_all(condition, self._states_in(condition.role, ctx),
                                            memory)
            elif vehicle is not None:
                holds, value = evaluate(condition, vehicle.state, memory)
            else:
                # No vehicle: what the engine keeps itself (elapsed times, the current
                # task) is still known; the checks (E275) allow nothing else here.
                holds, value = evaluate(condition, VehicleState(0, self._now), memory)
            if not holds:
                if log:
                    self._note("decision", f"{task.path_name}: skipped, condition false",
                               vid, task=task.path_name, subject=condition.subject,
                               expected=condition.value, read=value,
                               line=condition.location.line)
                return False
        return True


def _applies(event: Event, role: str | None) -> bool:
    return event.role is None or event.role == role
