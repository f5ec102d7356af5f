"""Semantic checks: the rules of the language that XSD 1.0 cannot express.

Every check runs and every finding is reported (not only the first): unknown action and
skill names, argument names, types, ranges and units, required and mutually exclusive
arguments, conditions that read unknown or misspelt parameters or compare them in a way
that does not fit their type, labels read before any MEMORIZE_POINT can have set them,
``current_task`` and JUMP_TO_TASK naming tasks that do not exist (or ambiguously), sibling
tasks with the same name, repeat counts below one, and actions that cannot be compiled to
mission items in a ``dispatch="mission"`` task.

Fleet missions (``<roles>`` and the orchestration of Dolphin) add their own rules: every
role named is declared once with a known vehicle type and a simple region; with several
roles each terminal task, and each condition that reads a vehicle, knows which vehicle it
means; orchestration that the interpreter cannot honour (a composition without sub-tasks,
``current_task`` in a gate, JUMP_TO_TASK between branches, an orchestrated part in an
autopilot-flown plan) is an error; roles no task uses and ``choice`` branches that can
never be chosen are warnings.
"""

from __future__ import annotations

import re
from collections import defaultdict
from collections.abc import Iterable

from tml.errors import Location, MissionSemanticError
from tml.language import actions, kinds, parameters, skills
from tml.language.diagnostics import Diagnostic, error, indefinite, warning
from tml.language.model import (
    Action,
    Argument,
    Comparison,
    Composition,
    Condition,
    ConditionKind,
    Dispatch,
    Mission,
    Role,
    Skill,
    Task,
    Termination,
    TerminationMode,
)
from tml.language.parameters import ParamType
from tml.language.quantities import MAX_ROUNDS, Quantity, out_of_range

# Built-in parameters the interpreter keeps itself; every other parameter (telemetry,
# recognitions, detection parameters) is read from a vehicle (tml.engine.conditions).
_INTERPRETER_PARAMETERS = frozenset({
    "MISSION_ELAPSED_TIME", "TASK_ELAPSED_TIME", "CURRENT_TASK", "CURRENT_ACTION",
    "ACTION_FAILURE"})


# Enum members the per-element checks compare with, bound once: reading a member from its
# class costs some 900 instructions more than reading a global (the enum class's lookup).
_MISSION = Dispatch.MISSION
_SEQUENCE = Composition.SEQUENCE
_CHOICE = Composition.CHOICE
_WRITE = actions.LabelUse.WRITE
_BY_PARAMETER = ConditionKind.PARAMETER
_BY_LABEL = ConditionKind.LABEL
_BY_CURRENT_TASK = ConditionKind.CURRENT_TASK
_KNOWN = Comparison.KNOWN


def _did_you_mean(word: str, candidates: Iterable[str]) -> str:
    import difflib  # here: a valid mission never needs it, so start-up does without

    guess = difflib.get_close_matches(word, list(candidates), n=1, cutoff=0.6)
    return f"did you mean {guess[0]!r}?" if guess else ""


def check(mission: Mission) -> list[Diagnostic]:
    """All semantic problems of a mission (errors and warnings)."""
    return _Checker(mission).run()


def check_jump(mission: Mission, target: str) -> list[Diagnostic]:
    """What the language says against a JUMP_TO_TASK to ``target`` in ``mission`` (empty:
    the jump is allowed): the rules of a written ``<termination mode="JUMP_TO_TASK">``,
    for a jump asked some other way (an operator's, through ``tml serve``). The
    diagnostics point at the mission element."""
    checker = _Checker(mission)
    checker.check_termination(Termination(TerminationMode.JUMP_TO_TASK, mission.location,
                                          target))
    return checker.found


class _Checker:
    def __init__(self, mission: Mission) -> None:
        self.mission = mission
        self.found: list[Diagnostic] = []
        self.tasks = list(mission.walk())
        self.by_name: dict[str, list[Task]] = defaultdict(list)
        for task in self.tasks:
            self.by_name[task.name].append(task)
        self.handlers = {id(h) for t in self.tasks for h in t.on_error}  # <on_error> tasks
        self.declared = {p.name: p for p in mission.parameters}
        self.switched = skills.switched(mission)
        self.unprovided: set[int] = set()  # ids of the conditions E225/E227/W301 was said of

    def run(self) -> list[Diagnostic]:
        self.check_declarations()
        self.check_roles()
        self.check_skills(self.mission.skills)
        self.check_tasks(self.mission.tasks)
        for event in self.mission.events:
            self.check_written_role(event.role, event.location)
            for condition in event.conditions:
                self.check_condition(condition)
                self.check_written_role(condition.role, condition.location)
            for action in event.actions:
                self.check_action(action, Dispatch.COMMAND)
            self.check_termination(event.termination)
        self.check_labels()
        self.check_mission_dispatch(self.mission.tasks, None)
        return self.found

    def at(self, where: Location, attribute: str) -> Location:
        """The location of ``attribute`` in the start tag at ``where``."""
        # Imported here: the engine checks an operator's jump with these rules, and must not
        # load the XML parser (lxml) that tml.language.xml holds.
        from tml.language.xml import attribute_location

        return attribute_location(self.mission.source, where, attribute)

    # --- declarations and skills -----------------------------------------------------------

    def check_declarations(self) -> None:
        seen: set[str] = set()
        for declaration in self.mission.parameters:
            builtin = parameters.lookup(declaration.name)
            if builtin is not None:
                self.found.append(error(
                    declaration.location, "E254",
                    f"parameter {declaration.name!r} is built in ({builtin.name}); "
                    "only detection parameters are declared"))
            elif declaration.name in seen:
                self.found.append(error(declaration.location, "E254",
                                        f"parameter {declaration.name!r} is declared twice"))
            seen.add(declaration.name)

    def check_skills(self, declared: Iterable[Skill]) -> None:
        names: set[str] = set()
        for skill in declared:
            spec = skills.lookup(skill.name)
            if spec is None:
                self.found.append(error(
                    skill.location, "E202", f"unknown skill {skill.name!r}",
                    _did_you_mean(skill.name.upper(), skills.skill_names())
                    or "known skills: " + ", ".join(s.name for s in skills.CATALOGUE)))
            elif spec.name in names:
                self.found.append(warning(skill.location, "W303",
                                          f"skill {spec.name} is declared twice here"))
            else:
                names.add(spec.name)

    # --- tasks -----------------------------------------------------------------------------

    def check_tasks(self, siblings: tuple[Task, ...], rounds: int = 1) -> None:
        """Check ``siblings``, each run ``rounds`` times by the repeats around them."""
        # An on_error task's path is its parent's path plus its name, like a sub-task's, so
        # the two share one name space.
        seen: dict[str, Task] = {}
        for task in siblings:
            if task.name in seen and self.handles(task, seen[task.name]):
                self.found.append(error(
                    task.location, "E244",
                    f"an <on_error> task and a sibling task are named {task.name!r} (the "
                    f"first at line {seen[task.name].location.line})",
                    "an error handler is named by its path: give it a name of its own"))
            elif task.name in seen:  # as Aerostack's own example missions do
                self.found.append(warning(
                    task.location, "W310",
                    f"two sibling tasks are named {task.name!r} (the first at line "
                    f"{seen[task.name].location.line}): current_task and JUMP_TO_TASK "
                    "cannot name either (E244)",
                    "give sibling tasks different names"))
            seen.setdefault(task.name, task)
            if task.skills:
                self.check_skills(task.skills)
            inner = self.check_repeat(task, rounds)
            for condition in task.conditions:
                self.check_condition(condition, guard=True)
            if task.action is not None:
                self.check_action(task.action, task.dispatch)
            self.check_orchestration(task)
            if task.children or task.on_error:
                self.check_tasks(task.children + task.on_error, inner)

    def handles(self, *tasks: Task) -> bool:
        """Whether one of ``tasks`` is an <on_error> task."""
        return any(id(task) in self.handlers for task in tasks)

    def check_repeat(self, task: Task, rounds: int) -> int:
        """Check a task's repeat count and the rounds nested repeats make of it; return the
        rounds its children run (1 once a problem is reported, so it is reported once)."""
        if task.repeat == 1:  # most tasks: in range, and no more rounds than around it
            return rounds
        where = task.repeat_location or task.location
        why = out_of_range(Quantity.REPEAT, float(min(task.repeat, 10**18)))
        if task.repeat < 1:
            self.found.append(error(
                where, "E250",
                f"repeat times={task.repeat} in task {task.name!r}; it must be 1 or more",
                "remove the task, or repeat it at least once"))
        elif why is not None:
            self.found.append(error(
                where, "E250", f"repeat times={task.repeat} in task {task.name!r} {why}",
                "use a <loop> with an <until> for a flight that goes on"))
        elif rounds * task.repeat > MAX_ROUNDS:
            self.found.append(error(
                where, "E250",
                f"task {task.name!r} runs {rounds * task.repeat:,} rounds through nested "
                f"repeats; at most {MAX_ROUNDS:,}",
                "repeat the inner or the outer task fewer times"))
        else:
            return rounds * task.repeat
        return 1

    # --- actions ---------------------------------------------------------------------------

    def check_action(self, action: Action, dispatch: Dispatch) -> None:
        spec = actions.lookup(action.name)
        if spec is None:
            self.found.append(error(
                action.location, "E201", f"unknown action {action.name!r}",
                _did_you_mean(action.name.upper().replace(" ", "_"), actions.action_names())
                or "see docs/language.md for the action catalogue"))
            return
        given: dict[str, str] = {}
        for argument in action.arguments:
            arg_spec = spec.argument(argument.name)
            if arg_spec is None:
                known = [a.name for a in spec.arguments]
                self.found.append(error(
                    argument.location, "E210",
                    f"{spec.name} has no argument {argument.name!r}",
                    _did_you_mean(argument.name, known)
                    or (f"{spec.name} takes: {', '.join(known)}" if known
                        else f"{spec.name} takes no arguments")))
                continue
            if arg_spec.name in given:
                self.found.append(error(
                    argument.location, "E217",
                    f"argument {arg_spec.name!r} of {spec.name} is given twice"))
                continue
            given[arg_spec.name] = argument.name
            if argument.label is not None:
                if arg_spec.label is None:
                    self.found.append(error(
                        argument.location, "E214",
                        f"argument {argument.name!r} of {spec.name} takes a value, not a label",
                        f'write value="..." ({arg_spec.type.value}'
                        + (f" in {arg_spec.unit}" if arg_spec.unit else "") + ")"))
            elif argument.value is not None:
                if arg_spec.label is _WRITE:
                    self.found.append(error(
                        argument.location, "E214",
                        f"argument {argument.name!r} of {spec.name} names the label to "
                        "memorize", f'write label="{argument.value}"'))
                    continue
                try:
                    actions.parse_value(arg_spec, argument.value)
                except ValueError as exc:
                    self.found.append(error(
                        argument.location, "E212",
                        f"argument {argument.name!r} of {spec.name} = {argument.value!r}: "
                        f"{exc}", arg_spec.description + (f" ({arg_spec.unit})"
                                                          if arg_spec.unit else "")))
        for arg_spec in spec.arguments:
            if arg_spec.required and arg_spec.name not in given:
                self.found.append(error(
                    action.location, "E211",
                    f"{spec.name} needs argument {arg_spec.name!r}",
                    f"{arg_spec.name}: {arg_spec.description}"
                    + (f" ({arg_spec.unit})" if arg_spec.unit else "")))
        for group in spec.exactly_one_of:
            present = [n for n in group if n in given]
            if len(present) != 1:
                self.found.append(error(
                    action.location, "E215",
                    f"{spec.name} needs exactly one of {', '.join(group)}; "
                    f"{'got ' + ', '.join(present) if present else 'none given'}"))
        for group in spec.at_most_one_of:
            present = [n for n in group if n in given]
            if len(present) > 1:
                self.found.append(error(
                    action.location, "E215",
                    f"{spec.name} takes at most one of {', '.join(group)}; "
                    f"got {', '.join(present)}"))
        for group in spec.together:
            present = [n for n in group if n in given]
            if present and len(present) != len(group):
                missing = [n for n in group if n not in given]
                self.found.append(error(
                    action.location, "E216",
                    f"{spec.name}: {', '.join(group)} go together; missing "
                    f"{', '.join(missing)}"))
        if dispatch is _MISSION and not spec.mission_item:
            self.found.append(error(
                action.location, "E260",
                f"{spec.name} cannot be flown as a mission item (dispatch=\"mission\")",
                'move it to a task with dispatch="command"'))
        elif dispatch is _MISSION:
            self.check_kept_by_autopilot(action, spec, given)
        if spec.mission_only and dispatch is not _MISSION:
            self.found.append(error(
                action.location, "E262",
                f"{spec.name} is flown only as a mission item: its task needs "
                'dispatch="mission"', 'set dispatch="mission" on the task or a task above it'))
        if spec.name == "MISSION_ITEM":
            self.check_raw_item(action)

    def check_raw_item(self, action: Action) -> None:
        """E263 for params a raw mission item cannot carry, W309 for a command number
        MAVLink does not define, W311 for values an autopilot takes but that look odd."""
        try:
            bound = actions.bind(action)
        except MissionSemanticError:
            return  # the argument checks above say why
        for problem in actions.raw_item_problems(bound.values):
            self.found.append(error(action.location, "E263", f"MISSION_ITEM: {problem}"))
        command = bound.text("command", "")  # absent: the checks above say so
        if command.isdigit():
            self.found.append(warning(
                action.location, "W309",
                f"MISSION_ITEM: command {command} is no MAV_CMD of ArduPilot's MAVLink "
                "dialect: an autopilot that does not know it refuses the upload"))
        for odd in actions.raw_item_oddities(bound.values):
            self.found.append(warning(action.location, "W311", f"MISSION_ITEM: {odd}"))

    def check_kept_by_autopilot(self, action: Action, spec: actions.ActionSpec,
                                given: dict[str, str]) -> None:
        """W307/W308: what the author wrote that ArduCopter's mission items do not keep
        (see docs/run.md, "What ArduCopter keeps of a plan")."""
        def value(name: str) -> object:
            argument = action.argument(given[name]) if name in given else None
            arg_spec = spec.argument(name)
            if argument is None or argument.value is None or arg_spec is None:
                return None
            try:
                return actions.parse_value(arg_spec, argument.value)
            except ValueError:
                return None  # E212 already says so

        if spec.name == "LOITER" and "radius" in given and "duration" in given:
            self.found.append(warning(
                action.location, "W307",
                "in a dispatch=\"mission\" task a LOITER with a duration is NAV_LOITER_TIME, "
                "of whose radius ArduPilot keeps only the direction: the radius is not flown "
                "(ArduCopter holds position over the centre)",
                "give turns to circle, or fly the task with dispatch=\"command\""))
        if value("precision_mode") == "required":
            self.found.append(warning(
                action.location, "W308",
                "ArduCopter keeps no precision-landing mode in a mission's NAV_LAND: it lands "
                "on a target whenever its PLND_ENABLED parameter is 1, and without one "
                "otherwise, so \"required\" is not enforced",
                "set PLND_ENABLED (and PLND_STRICT) on the vehicle, or land with "
                "dispatch=\"command\""))

    # --- conditions ------------------------------------------------------------------------

    def check_condition(self, condition: Condition, guard: bool = False) -> None:
        """Check a condition; ``guard``: it is a task's own ``<condition>``."""
        if not condition.subject:
            return  # the builder already reported the missing subject
        if condition.kind is _BY_CURRENT_TASK:
            self.resolve_task(condition.subject, condition, "current_task")
            return
        # An unknown parameter is said whatever else is wrong with the condition.
        param_type = self.parameter_type(condition, guard) \
            if condition.kind is _BY_PARAMETER else None
        if condition.comparison is None:
            self.found.append(error(
                condition.location, "E221", "the condition has no comparison=",
                "one of: " + ", ".join(c.value for c in Comparison)))
            return
        if condition.kind is _BY_LABEL:
            if condition.comparison is not _KNOWN:
                self.found.append(error(
                    condition.location, "E223",
                    f"a label is tested with comparison=\"known\", not "
                    f"{condition.comparison.value!r}"))
            self.check_known_value(condition)
            return
        if condition.comparison is _KNOWN:
            self.check_known_value(condition)
            return
        if condition.value is None:
            self.found.append(error(condition.location, "E222",
                                    "the condition has no value=", "add value=\"...\""))
            return
        if param_type is None:
            return
        if condition.comparison not in parameters.COMPARISONS[param_type]:
            fitting = sorted(c.value for c in parameters.COMPARISONS[param_type])
            self.found.append(error(
                condition.location, "E223",
                f"{condition.subject!r} is {indefinite(param_type.value)}; comparison "
                f"{condition.comparison.value!r} does not apply",
                "use one of: " + ", ".join(fitting)))
            return
        self.check_value(condition, param_type)

    def parameter_type(self, condition: Condition, guard: bool = False) -> ParamType | None:
        """The type of the parameter ``condition`` reads, or None (said why) when nothing
        provides it; ``guard``: the condition is a task's own ``<condition>``."""
        spec = parameters.lookup(condition.subject)
        if spec is not None:
            return spec.type
        declared = self.declared.get(condition.subject)
        if declared is not None:
            return ParamType(declared.type)
        found = parameters.found_in(condition.subject)
        feeders = skills.feeders(found[0]) if found is not None else ()
        if self.switched & set(feeders):
            return ParamType.BOOLEAN  # true while the id is in the set
        self.unprovided.add(id(condition))  # nothing else is said of what it reads
        guess = parameters.suggest(condition.subject)
        if guess is not None:
            self.found.append(error(
                condition.location, "E225",
                f"unknown parameter {condition.subject!r}", f"did you mean {guess!r}?"))
            return None
        needed = parameters.type_for(condition.comparison, condition.value)
        declare = f'<parameter name="{condition.subject}" type="{needed.value}"/>'
        if found is not None:
            self.found.append(error(
                condition.location, "E227",
                f"nothing provides parameter {condition.subject!r}: it reads {found[0]}, "
                "which no skill the mission switches on fills",
                f'switch on {" or ".join(feeders)} with <skill name="{feeders[0]}"/>, or '
                f"declare it: {declare}"))
            return None
        meant = parameters.closest(condition.subject, self.declared)
        if meant is None and guard and condition.comparison in (
                Comparison.EQUAL, Comparison.NOT_EQUAL) and condition.value is not None \
                and parameters.parse_number(condition.value) is None:
            # The paper's Example 2 ("observed color" equal "green"): TML as published has
            # no <parameter>, so its guard stays valid; a guard never true skips its task,
            # which the flight shows.
            self.found.append(warning(
                condition.location, "W301",
                f"nothing provides parameter {condition.subject!r} (not built in, not "
                "declared, fed by no skill): the condition is never true, so the task is "
                "always skipped", f"declare it if something on the vehicle reports it: "
                f"{declare}"))
            return None
        # A comparison with an unknown value is false, except known="no".
        always = condition.comparison is Comparison.KNOWN and condition.value is not None \
            and parameters.parse_boolean(condition.value) is False
        self.found.append(error(
            condition.location, "E227",
            f"nothing provides parameter {condition.subject!r}: it is not built in, not "
            "declared with <parameter>, and no skill the mission switches on feeds it, so "
            f"the condition is {'always' if always else 'never'} true",
            f"did you mean {meant!r}?" if meant is not None
            else f"declare it if a companion computer reports it: {declare}"))
        return None

    def check_known_value(self, condition: Condition) -> None:
        if condition.value is not None and parameters.parse_boolean(condition.value) is None:
            self.found.append(error(
                condition.location, "E224",
                f"comparison \"known\" takes value \"yes\" or \"no\", not {condition.value!r}"))

    def check_value(self, condition: Condition, param_type: ParamType) -> None:
        value = condition.value or ""
        if param_type is ParamType.NUMBER or (
                param_type is ParamType.SET and condition.comparison is Comparison.INCLUDES
                and self.numeric_set(condition)):
            number = parameters.parse_number(value)
            spec = parameters.lookup(condition.subject)
            why = (out_of_range(spec.quantity, number)
                   if number is not None and spec is not None and spec.quantity else None)
            if number is None:
                self.found.append(error(
                    condition.location, "E224",
                    f"{condition.subject!r} is a number; value {value!r} is not"))
            elif why is not None and spec is not None:
                self.found.append(error(
                    condition.location, "E224",
                    f"{spec.name} value {value!r} {why}"))
        elif param_type is ParamType.BOOLEAN:
            if parameters.parse_boolean(value) is None:
                self.found.append(error(
                    condition.location, "E224",
                    f"{condition.subject!r} is yes/no; value {value!r} is neither"))
        elif param_type is ParamType.STRING:
            spec = parameters.lookup(condition.subject)
            if spec is not None and spec.values and value not in spec.values:
                self.found.append(error(
                    condition.location, "E226",
                    f"{spec.name} is never {value!r}",
                    "its values are: " + ", ".join(spec.values)))
            if spec is not None and spec.name == "CURRENT_TASK":
                self.resolve_task(value, condition, "value")

    @staticmethod
    def numeric_set(condition: Condition) -> bool:
        spec = parameters.lookup(condition.subject)
        return spec is not None and "MARKERS" in spec.name

    # --- task references -------------------------------------------------------------------

    def resolve_task(self, reference: str, where: Condition | object, what: str) -> None:
        location = getattr(where, "location")  # noqa: B009 - conditions and terminations
        if "/" in reference:
            path = tuple(part.strip() for part in reference.split("/"))
            same = [task for task in self.tasks if task.path == path]
            if len(same) > 1:
                self.found.append(error(
                    location, "E244", f"{what} {reference!r} is ambiguous: {len(same)} "
                    "sibling tasks have this path", "give sibling tasks different names"))
            if same:
                return
            self.found.append(error(
                location, "E240", f"{what} {reference!r}: no task has this path",
                _did_you_mean(reference, [t.path_name for t in self.tasks])))
            return
        matches = self.by_name.get(reference.strip(), [])
        if len(matches) == 1:
            return
        if not matches:
            self.found.append(error(
                location, "E240", f"{what} {reference!r}: no task has this name",
                _did_you_mean(reference, list(self.by_name))))
        else:
            self.found.append(error(
                location, "E244",
                f"{what} {reference!r} is ambiguous: {len(matches)} tasks have this name",
                "write the path instead: " + " or ".join(repr(t.path_name) for t in matches)))

    def check_termination(self, termination: Termination) -> None:
        mode = termination.mode
        if mode is TerminationMode.JUMP_TO_TASK:
            if self.has_branches():
                self.found.append(error(
                    self.at(termination.location, "mode"), "E283",
                    "JUMP_TO_TASK is not allowed in a mission with roles or orchestration",
                    "a branch cannot jump into another; use NEXT_TASK, ABORT_TASK or "
                    "REPEAT_TASK within the branch, or an <on_error> handler"))
            elif not termination.task:
                self.found.append(error(
                    termination.location, "E242", "JUMP_TO_TASK needs task=\"...\"",
                    "name the task to jump to"))
            else:
                self.resolve_task(termination.task, termination, "JUMP_TO_TASK target")
        elif termination.task:
            self.found.append(warning(
                termination.location, "W304",
                f"task= is only used by JUMP_TO_TASK; ignored with {mode.value}"))

    # --- labels ----------------------------------------------------------------------------

    def check_labels(self) -> None:
        set_in_tasks: dict[str, list[int]] = defaultdict(list)
        set_by_events: set[str] = set()
        reads: list[tuple[str, int | None, Argument]] = []
        # Every action with its task's index in document order (None: an event's), as
        # Mission.actions() gives them.
        held: list[tuple[int | None, Action]] = [
            (index, task.action) for index, task in enumerate(self.tasks)
            if task.action is not None]
        held += [(None, action) for event in self.mission.events for action in event.actions]
        for index, action in held:
            for label, use, argument in self.label_arguments(action):
                if use is _WRITE:
                    if index is None:
                        set_by_events.add(label)
                    else:
                        set_in_tasks[label].append(index)
                else:
                    reads.append((label, index, argument))
        # Document order is flight order unless tasks repeat, loop, run side by side, or an
        # event sends the flight back.
        loops_back = bool(reads) and (any(
            task.repeat > 1 or task.loop is not None
            or task.composition is not _SEQUENCE for task in self.tasks) or any(
            e.termination.mode in (TerminationMode.JUMP_TO_TASK, TerminationMode.REPEAT_TASK)
            for e in self.mission.events))
        known = set(set_in_tasks) | set_by_events
        tested = [c for t in self.tasks
                  if t.conditions or t.wait_for or t.until or t.loop is not None
                  for c in _all_conditions(t)] + [
            c for e in self.mission.events for c in e.conditions]
        for condition in tested:
            if condition.kind is _BY_LABEL and condition.subject \
                    and condition.subject not in known:
                self.found.append(error(
                    condition.location, "E232",
                    f"label {condition.subject!r} is tested but no MEMORIZE_POINT ever "
                    "stores it, so the test never changes",
                    _did_you_mean(condition.subject, known) or "check the label's spelling"))
        for label, index, argument in reads:
            if label not in known:
                self.found.append(error(
                    argument.location, "E230",
                    f"label {label!r} is read but no MEMORIZE_POINT ever stores it",
                    _did_you_mean(label, known) or
                    f'memorize it first: <action name="MEMORIZE_POINT"><argument '
                    f'name="coordinates" label="{label}"/></action>'))
            elif (index is not None and label not in set_by_events and not loops_back
                  and min(set_in_tasks[label]) > index):
                self.found.append(error(
                    argument.location, "E231",
                    f"label {label!r} is read before the MEMORIZE_POINT that stores it "
                    f"(task at line {self.tasks[min(set_in_tasks[label])].location.line})",
                    "memorize the point in an earlier task"))

    @staticmethod
    def label_arguments(action: Action) -> list[tuple[str, actions.LabelUse, Argument]]:
        for argument in action.arguments:
            if argument.label:
                break
        else:
            return []  # most actions: no label to store or read
        spec = actions.lookup(action.name)
        if spec is None:
            return []
        found = []
        for argument in action.arguments:
            arg_spec = spec.argument(argument.name)
            if arg_spec is not None and arg_spec.label is not None and argument.label:
                found.append((argument.label, arg_spec.label, argument))
        return found

    # --- fleets: roles ---------------------------------------------------------------------

    def check_roles(self) -> None:
        seen: dict[str, Role] = {}
        for role in self.mission.roles:
            if role.name in seen:
                self.found.append(error(
                    self.at(role.location, "name"), "E271",
                    f"role {role.name!r} is declared twice (first at line "
                    f"{seen[role.name].location.line})", "give each role its own name"))
            seen.setdefault(role.name, role)
            wanted = role.vehicle_type
            if wanted is not None and not any(kinds.vehicle_type_matches(wanted, actual)
                                               for actual in kinds.VEHICLE_TYPES):
                known_types = sorted(kinds.VEHICLE_TYPES | kinds.VEHICLE_TYPE_CLASSES)
                self.found.append(error(
                    self.at(role.location, "type"), "E272",
                    f"role {role.name!r}: unknown vehicle type {wanted!r}",
                    _did_you_mean(wanted, known_types)
                    or "known types: " + ", ".join(known_types)))
            if role.region is not None and not role.region.is_circle:
                reason = _polygon_problem(role.region.points)
                if reason:
                    self.found.append(error(
                        role.region.location, "E273",
                        f"the region of role {role.name!r} is not a simple polygon: {reason}",
                        "list the corners in order around the region, without crossing "
                        "edges"))
        flown = {task.role for task in self.tasks}
        for role in self.mission.roles:
            if role.name not in flown and seen[role.name] is role:
                self.found.append(warning(
                    role.location, "W305", f"no task is flown by role {role.name!r}",
                    f'write role="{role.name}" on the tasks it flies, or remove the role'))

    def check_role_name(self, name: str | None, where: Location) -> None:
        """E270 when ``name`` (written at ``where``) is no declared role."""
        if name is None or self.mission.role(name) is not None:
            return
        declared = list(dict.fromkeys(r.name for r in self.mission.roles))
        self.found.append(error(
            where, "E270", f"no role is named {name!r}",
            _did_you_mean(name, declared)
            or ("declared roles: " + ", ".join(declared) if declared
                else "declare it: <roles><role name=\"" + name + "\"/></roles>")))

    def check_written_role(self, name: str | None, element: Location) -> None:
        """E270 when ``name``, written as role= on the element at ``element``, is no
        declared role."""
        if name is not None:  # the attribute is found in the text only when it is written
            self.check_role_name(name, self.at(element, "role"))

    # --- fleets: orchestration -------------------------------------------------------------

    def check_orchestration(self, task: Task) -> None:
        if task.role_location is not None:
            self.check_role_name(task.role, task.role_location)
        for name in task.release:
            self.check_role_name(name, task.release_location or task.location)
        if len(self.mission.roles) > 1 and task.is_terminal and task.role is None:
            self.found.append(error(
                task.location, "E274",
                f"task {task.name!r} is flown by no role, and the mission has "
                f"{len(self.mission.roles)}: which vehicle flies it?",
                "write role=\"...\" on the task or on a task above it"))
        if task.is_terminal and task.composition is not _SEQUENCE:
            self.found.append(error(
                self.at(task.location, "composition"), "E280",
                f'composition="{task.composition.value}" on task {task.name!r}, which has '
                "an action and no sub-tasks", "composition says how sub-tasks run; remove it"))
        gated = [(tag, c) for tag, conditions in (
            ("wait_for", task.wait_for), ("until", task.until),
            ("loop", task.loop.conditions if task.loop else ())) for c in conditions] \
            if task.wait_for or task.until or task.loop is not None else []
        for tag, condition in gated:
            if condition.kind is _BY_CURRENT_TASK:
                self.found.append(error(
                    condition.location, "E281",
                    f"current_task in <{tag}> of task {task.name!r}",
                    f"<{tag}> is checked while the task itself is current (or about to be); "
                    "test a parameter or a label instead"))
            else:
                self.check_condition(condition)
        for condition in _all_conditions(task) if task.conditions or gated else ():
            self.check_written_role(condition.role, condition.location)
            if (self.mission.roles and task.role is None and condition.role is None
                    and condition.kind is _BY_PARAMETER and condition.subject
                    and id(condition) not in self.unprovided
                    and self.reads_vehicle(condition.subject)):
                self.found.append(error(
                    condition.location, "E275",
                    f"{condition.subject!r} is read from a vehicle, but task {task.name!r} "
                    "is flown by no role: which vehicle's?",
                    'name it: role="..." on the condition or on the task'))
        if task.composition is _CHOICE:
            self.check_choice(task)

    @staticmethod
    def reads_vehicle(subject: str) -> bool:
        spec = parameters.lookup(subject)
        return spec is None or spec.name not in _INTERPRETER_PARAMETERS

    def check_choice(self, task: Task) -> None:
        always = next((c for c in task.children if not c.conditions), None)
        if always is None:
            return
        for child in task.children[task.children.index(always) + 1:]:
            self.found.append(warning(
                child.location, "W306",
                f"task {child.name!r} is never chosen: {always.name!r} before it has no "
                "condition, so it is always chosen first",
                "give the earlier branch a condition, or move the unconditional branch last"))

    def has_branches(self) -> bool:
        """True when the mission has roles or orchestration: tasks that run side by side."""
        return bool(self.mission.roles) or any(
            task.orchestrated or task.role_location is not None for task in self.tasks)

    def check_mission_dispatch(self, siblings: tuple[Task, ...], parent: Task | None) -> None:
        """E261 for each task whose ``dispatch="mission"`` plan cannot be one plan."""
        for task in siblings:
            # Command-flown sub-trees of a plan may start plans of their own.
            self.check_mission_dispatch(task.children + task.on_error, task)
            starts_plan = task.dispatch is _MISSION and (
                parent is None or parent.dispatch is not _MISSION)
            if not starts_plan:
                continue
            plan = _plan_tasks(task)
            orchestrated = next((t for t in plan if t.orchestrated), None)
            roles = sorted({t.role or "none" for t in plan})
            if orchestrated is not None or len(roles) > 1:
                if orchestrated is task:
                    why = "it uses orchestration"
                elif orchestrated is not None:
                    why = (f"task {orchestrated.name!r} (line {orchestrated.location.line}) "
                           "in it uses orchestration")
                else:
                    why = "its sub-tasks are flown by roles " + ", ".join(roles)
                self.found.append(error(
                    self.at(task.location, "dispatch"), "E261",
                    f'task {task.name!r} is flown as one autopilot plan (dispatch="mission"), '
                    f"but {why}",
                    "the autopilot flies one plan on one vehicle; use dispatch=\"mission\" "
                    "on the plain tasks inside"))


def _all_conditions(task: Task) -> list[Condition]:
    """A task's own conditions, and those of its wait_for, until and loop."""
    return [*task.conditions, *task.wait_for, *task.until,
            *(task.loop.conditions if task.loop else ())]


def _plan_tasks(task: Task) -> list[Task]:
    """The tasks of the autopilot plan that ``task`` starts (sub-trees flown by command
    are not part of it)."""
    found = [task]
    for child in task.children + task.on_error:
        if child.dispatch is _MISSION:
            found.extend(_plan_tasks(child))
    return found


def _polygon_problem(points: tuple[tuple[float, float], ...]) -> str:
    """Why the corners do not make a simple polygon with an area ('' if they do)."""
    from shapely.geometry import Polygon  # only missions with polygon regions need it
    from shapely.validation import explain_validity

    polygon = Polygon([(east, north) for north, east in points])
    if polygon.is_valid:
        return ""
    if polygon.convex_hull.area < 1e-6:
        return "its corners are on one line"
    reason = explain_validity(polygon)  # "Self-intersection[east north]"
    where = re.fullmatch(r"(.*)\[(\S+) (\S+)\]", reason)
    if where is None:
        return reason.lower()
    return (f"{where.group(1).lower()} at north {float(where.group(3)):g} m, "
            f"east {float(where.group(2)):g} m")
