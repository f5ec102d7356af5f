"""When an interpreter has to be stepped again: what its running nodes wait for.

Theory of operation
-------------------
A step of the interpreter changes something only when something it reads has changed: a
request's result, a lost vehicle, an operator's control, the time, or a vehicle's state.
After each step, every running node tells a :class:`Waker` what it waits for (the tree
from the root, and the event handling), and :meth:`Waker.wake` sums that up as a
:class:`Wake`: the time of the next step that time alone makes worth taking, and which
fields of which vehicle's state matter. A runner that steps the interpreter again only
then, or on a result, a lost vehicle or a control, misses nothing: a step taken in
between would have done nothing.

A node that does not say what it waits for -- the default of
:meth:`tml.engine.composites.Node.wake` -- waits for anything (:meth:`Waker.anything`): it
is stepped at the runner's rate, and on any change of any vehicle, as before the wake
existed. Only nodes whose next move is certain say more: an action waiting for its
request's answer waits for nothing else, a WAIT for its time, a task's time limit for
that time, an ``Until`` (a climb, a GO_TO, a landing) for its vehicle to show something
new or its picture to become current, the event handlers for the fields their conditions
read. So the common case of a large fleet -- most vehicles flying a long wait or a
request, while their positions change with every message -- costs a step only when a
field an event reads changes (a battery's percentage), not on every message.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from tml.engine.conditions import ENGINE_PARAMETERS, STATE_FIELDS
from tml.language import parameters
from tml.language.model import Condition, ConditionKind
from tml.vehicle import SHOWN_FIELDS


@dataclass(frozen=True)
class Wake:
    """When to step an interpreter again, besides results, lost vehicles and controls.

    ``at``: the earliest time (the runner's clock) at which time alone may change what a
    step does; -inf: at the runner's rate. ``reads``: per vehicle, the fields of its
    :class:`~tml.vehicle.VehicleState` whose change calls for a step (None for a vehicle:
    any field it compares; a vehicle left out: none); ``reads`` None: any field of any
    vehicle.
    """

    at: float
    reads: Mapping[int, frozenset[str] | None] | None


ANYTHING = Wake(-math.inf, None)
"""The wake of an interpreter that cannot say more: every tick and every change."""


class Waker:
    """Collects what the running nodes wait for (see the module docstring)."""

    def __init__(self) -> None:
        self.at = math.inf
        self.reads: dict[int, frozenset[str] | None] | None = {}
        self.vehicles: set[int] = set()  # whose work the nodes are (see vehicle)

    def anything(self) -> None:
        """Wait for anything: every tick, every change of every vehicle."""
        self.at = -math.inf
        self.reads = None

    def by(self, at: float) -> None:
        """Step at ``at`` (the mission's clock) at the latest."""
        self.at = min(self.at, at)

    def vehicle(self, vehicle_id: int) -> None:
        """The nodes do a vehicle's work: what is done to that work from outside (a
        result handed over, an event handler's hold or verdict) calls for a step."""
        self.vehicles.add(vehicle_id)

    def state(self, vehicle_id: int, fields: frozenset[str] | None = None) -> None:
        """A change of these ``fields`` of a vehicle's state calls for a step (None: any)."""
        if self.reads is None:
            return
        reads = self.reads
        if vehicle_id not in reads:
            reads[vehicle_id] = fields
            return
        known = reads[vehicle_id]
        if fields is None or known is None:
            reads[vehicle_id] = None
        elif not fields <= known:
            reads[vehicle_id] = known | fields

    def tell(self, other: Waker) -> None:
        """Add what this one collected to ``other``."""
        if self.reads is None:
            other.anything()
            return
        other.by(self.at)
        other.vehicles |= self.vehicles
        for vehicle_id, fields in self.reads.items():
            other.state(vehicle_id, fields)

    def wake(self, offset: float) -> Wake:
        """The sum, with times moved from the mission's clock to the runner's by
        ``offset`` (the time the run spent paused)."""
        return Wake(self.at + offset, self.reads)


def fields_read(reads: Mapping[int, frozenset[str] | None] | None,
                vehicle_id: int) -> Iterable[str]:
    """The fields of a vehicle's state whose change calls for a step, by :attr:`Wake.reads`
    (or a :class:`Waker`'s ``reads``)."""
    if reads is None:
        return SHOWN_FIELDS
    names = reads.get(vehicle_id, ())
    return SHOWN_FIELDS if names is None else names


def condition_fields(condition: Condition) -> frozenset[str] | None:
    """The fields of its vehicle's state a condition reads; None when it reads more than
    one vehicle's state (the interpreter's own, another role's vehicles)."""
    if condition.role is not None or condition.kind in (ConditionKind.CURRENT_TASK,
                                                        ConditionKind.LABEL):
        return None
    spec = parameters.lookup(condition.subject)
    if spec is None:
        return DETECTIONS  # a detection parameter
    if spec.name in ENGINE_PARAMETERS:
        return None
    return STATE_FIELDS.get(spec.name, DETECTIONS)


DETECTIONS = frozenset({"detections"})
