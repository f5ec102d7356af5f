"""Pre-flight clearance: the one source of the rules a mission passes before anything is sent.

Theory of operation
-------------------
:func:`clear` holds a mission against the vehicles chosen to fly it (all of a ``tml run``,
a run's subset of a ``tml serve`` fleet) and returns :class:`Cleared`, with the profile to
fly with, or :class:`NotCleared`, with the :class:`Refusal` a command maps to its exit code
or HTTP status. Its checks, in this order, each stopping the clearance when it refuses:

1. the mission verified with the profile given (:func:`tml.verify.static.verify_mission`,
   with the ``extra`` world): infeasible is refused unless ``force``;
2. the actions the vehicles cannot do at all (:func:`tml.verify.inflight.preflight`):
   refused unless ``force``;
3. each vehicle's own reaction to a lost ground station (``FS_GCS_ENABLE``), when
   ``gcs_failsafe`` asks for it: a warning, or a refusal with ``require_gcs_failsafe``
   (``force`` does not fly over it: it is about the vehicle, not the mission);
4. without a profile (``--profile vehicle``), the shipped profile of the first vehicle's kind
   filled in from its parameters, and the mission verified with it as in 1.

What was found is data (:data:`Finding`), in the order found, in either answer: ``tml run``
says it on its error console (:func:`say`); ``tml serve`` puts the refusing finding in its
JSON error (a forced finding or a warning it does not say).

A mission verified before its vehicles are opened (``tml run`` with a shipped profile, so
that a mission it would refuse connects to nothing) is cleared with ``verified``: step 1 is
not done again.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, runtime_checkable

if TYPE_CHECKING:
    from rich.console import Console

    from tml.language.model import Mission
    from tml.vehicle import Vehicle
    from tml.verify.constraints import Violation
    from tml.verify.profile import VehicleProfile
    from tml.verify.static import Report
    from tml.world import World

GCS_FAILSAFE = "FS_GCS_ENABLE"
"""ArduPilot's parameter for what a vehicle does by itself when its ground station falls
silent (0: nothing; 1 RTL, 5 LAND ...; see docs/run.md)."""
GCS_SYSTEM = ("MAV_GCS_SYSID", "SYSID_MYGCS")
"""ArduPilot's parameter for the system id of its ground station, under ArduPilot 4.7's name
and the one before it: its GCS failsafe counts only that system's HEARTBEATs, and one never
heard arms no failsafe (docs/run.md)."""
GCS_SYSTEM_HIGH = "MAV_GCS_SYSID_HI"
"""ArduPilot 4.7.1's upper end of a range of ground-station system ids (from MAV_GCS_SYSID;
no range unless above it)."""


class Refusal(enum.Enum):
    """Why a mission was not cleared for flight."""

    MISSION = "mission"
    """The mission: infeasible, or with actions its vehicles cannot do (exit 1)."""
    VEHICLE = "vehicle"
    """A vehicle: no failsafe of its own while one is required, or no parameters to read
    its profile from (exit 4)."""


@dataclass(frozen=True)
class ClearanceOptions:
    """What a command decides about the clearance."""

    force: bool = False
    """Fly a mission refused as infeasible or beyond its vehicles anyway."""
    gcs_failsafe: bool = True
    """Read each vehicle's ``FS_GCS_ENABLE`` (a warning when it does nothing)."""
    require_gcs_failsafe: bool = False
    """Refuse a vehicle whose ``FS_GCS_ENABLE`` does nothing (read even without
    ``gcs_failsafe``)."""


@runtime_checkable
class ReadsParameters(Protocol):
    """A vehicle whose parameters can be read (a MAVLink vehicle; not a test's fake)."""

    def read_parameters(self, names: Iterable[str]) -> Mapping[str, float]: ...

    def read_first(self, names: Sequence[str]) -> tuple[str, float] | None: ...

    @property
    def source_system(self) -> int: ...


@dataclass(frozen=True)
class Infeasible:
    """The verifier's report of an infeasible mission; ``forced``: flown anyway."""

    report: Report
    forced: bool


@dataclass(frozen=True)
class Incapable:
    """Actions the vehicles cannot do at all, each naming its vehicle (and role);
    ``forced``: flown anyway."""

    violations: tuple[Violation, ...]
    forced: bool


@dataclass(frozen=True)
class FailsafeMissing:
    """Vehicles that do nothing by themselves when their ground station falls silent, one
    line each; ``required``: refused for it."""

    problems: tuple[str, ...]
    required: bool


@dataclass(frozen=True)
class ProfileRead:
    """The profile filled in from a vehicle's parameters (those it had)."""

    profile: VehicleProfile
    vehicle_id: int
    parameters: Mapping[str, float]


@dataclass(frozen=True)
class NoParameters:
    """The profile was to be read from a vehicle that does not report its parameters."""

    vehicle_id: int


Finding = Infeasible | Incapable | FailsafeMissing | ProfileRead | NoParameters
"""What the clearance found, in the order it found it."""


@dataclass(frozen=True)
class Cleared:
    """The mission may fly, with ``profile``; ``findings``: warnings, forced refusals."""

    profile: VehicleProfile
    findings: tuple[Finding, ...] = ()


@dataclass(frozen=True)
class NotCleared:
    """The mission must not fly; the last of ``findings`` is why."""

    refusal: Refusal
    findings: tuple[Finding, ...]

    @property
    def reason(self) -> Finding:
        """The finding that refused."""
        return self.findings[-1]


def clear(mission: Mission, vehicles: Sequence[Vehicle], profile: VehicleProfile | None,
          extra: World | None = None, options: ClearanceOptions | None = None, *,
          verified: bool = False) -> Cleared | NotCleared:
    """Clear ``mission`` for flight on ``vehicles`` (none: only its verification) with
    ``profile`` (None: read from the first vehicle) and the ``extra`` world; see the module
    docstring. Reads the vehicles' parameters; sends nothing else."""
    options = options or ClearanceOptions()
    found: list[Finding] = []
    if profile is not None and not verified:
        infeasible = _verify(mission, profile, extra, options)
        if infeasible is not None:
            found.append(infeasible)
            if not infeasible.forced:
                return NotCleared(Refusal.MISSION, tuple(found))
    if vehicles:
        from tml.verify.inflight import preflight

        cannot = preflight(mission, {v.vehicle_id: v.state().vehicle_type for v in vehicles})
        if cannot:
            found.append(Incapable(tuple(cannot), options.force))
            if not options.force:
                return NotCleared(Refusal.MISSION, tuple(found))
    if options.gcs_failsafe or options.require_gcs_failsafe:
        missing = failsafe_missing(vehicles, options.require_gcs_failsafe)
        if missing is not None:
            found.append(missing)
            if missing.required:
                return NotCleared(Refusal.VEHICLE, tuple(found))
    if profile is None:
        read = _profile_read(vehicles[0])
        found.append(read)
        if isinstance(read, NoParameters):
            return NotCleared(Refusal.VEHICLE, tuple(found))
        profile = read.profile
        infeasible = _verify(mission, profile, extra, options)
        if infeasible is not None:
            found.append(infeasible)
            if not infeasible.forced:
                return NotCleared(Refusal.MISSION, tuple(found))
    return Cleared(profile, tuple(found))


def failsafe_missing(vehicles: Sequence[Vehicle], required: bool) -> FailsafeMissing | None:
    """The vehicles that would do nothing by themselves when tml falls silent
    (:func:`failsafe_problem`), one line each (``required``: refused), or None."""
    problems = [f"vehicle {vehicle.vehicle_id}: {problem}" for vehicle in vehicles
                if (problem := failsafe_problem(vehicle)) is not None]
    return FailsafeMissing(tuple(problems), required) if problems else None


def failsafe_problem(vehicle: Vehicle) -> str | None:
    """Why ``vehicle`` would do nothing by itself when tml falls silent, or None: without a
    reaction of its own, a vehicle whose link dies hovers until its battery runs out.

    Read: ``FS_GCS_ENABLE``; then the system id of its ground station (:data:`GCS_SYSTEM`),
    which must be the one tml sends as, or the failsafe never hears tml: ArduPilot arms it
    on its ground station's first HEARTBEAT and counts only that station's (and the range
    up to :data:`GCS_SYSTEM_HIGH`, read only when the id differs)."""
    unknown = f"{GCS_FAILSAFE} not reported: what the vehicle does when it loses this " \
              "ground station is unknown"
    if not isinstance(vehicle, ReadsParameters):
        return unknown
    value = vehicle.read_parameters([GCS_FAILSAFE]).get(GCS_FAILSAFE)
    if value is None:
        return unknown
    if value == 0:
        return f"{GCS_FAILSAFE} is 0: the vehicle does nothing by itself when it loses this " \
               "ground station (1 returns home, 5 lands)"
    station = vehicle.read_first(GCS_SYSTEM)
    if station is None:
        return None  # neither name: nothing to compare
    name, low = station[0], round(station[1])
    ours = vehicle.source_system
    if low == ours:
        return None
    high = vehicle.read_parameters([GCS_SYSTEM_HIGH]).get(GCS_SYSTEM_HIGH) \
        if name == GCS_SYSTEM[0] else None
    if high is not None and low <= ours <= round(high):
        return None
    return (f"{name} is {low} and tml sends as system {ours}: the vehicle's GCS failsafe "
            f"hears only system {low}'s HEARTBEATs, so it does nothing by itself when this "
            f"ground station falls silent (set {name} to {ours})")


def _verify(mission: Mission, profile: VehicleProfile, extra: World | None,
            options: ClearanceOptions) -> Infeasible | None:
    from tml.verify.static import verify_mission

    report = verify_mission(mission, profile, extra)
    return None if report.feasible else Infeasible(report, options.force)


def _profile_read(vehicle: Vehicle) -> ProfileRead | NoParameters:
    """The shipped profile of the vehicle's kind filled in from its own parameters."""
    from tml.verify.profile import profile_from_vehicle, shipped_for

    if not isinstance(vehicle, ReadsParameters):
        return NoParameters(vehicle.vehicle_id)
    profile, params = profile_from_vehicle(vehicle.read_parameters,
                                           shipped_for(vehicle.state().vehicle_type))
    return ProfileRead(profile, vehicle.vehicle_id, params)


def say(findings: Iterable[Finding], file: str, program: str, force: bool,
        errors: Console) -> None:
    """Say what the clearance found on ``errors`` as ``tml run`` does: each line begins
    with ``program``, a refused mission's with its ``file``."""
    def line(text: str) -> None:
        errors.print(text, markup=False, highlight=False)

    def refused(what: str) -> None:
        line(f"{program}: {what} flown anyway (--force)" if force else
             f"{program}: {file}: {what}, not flown (--force flies it anyway)")

    for finding in findings:
        if isinstance(finding, Infeasible):
            from tml.verify.report import print_report

            print_report(finding.report, errors)
            refused("infeasible mission")
        elif isinstance(finding, Incapable):
            for violation in finding.violations:
                whose = f" (role {violation.role})" if violation.role else ""
                line(f"{violation} (vehicle {violation.vehicles[0]}{whose})")
            refused("mission with actions its vehicles cannot do")
        elif isinstance(finding, FailsafeMissing):
            for problem in finding.problems:
                line(f"{program}: {'' if finding.required else 'warning: '}{problem}")
            if finding.required:
                line(f"{program}: not flown (--require-gcs-failsafe)")
        elif isinstance(finding, ProfileRead):
            from tml.verify.profile import describe_parameters

            line(f"{program}: {finding.profile.name} profile from vehicle "
                 f"{finding.vehicle_id}'s parameters: "
                 + describe_parameters(finding.parameters))
        else:
            line(f"{program}: profile 'vehicle': vehicle {finding.vehicle_id} does not "
                 "report its parameters")
