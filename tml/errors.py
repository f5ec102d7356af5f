"""The one error hierarchy of tml, and the exit codes its commands end with.

Mission errors (what the author wrote) are apart from vehicle and link errors (what
happened in flight). Every mission error carries the file, line and column it is about;
every vehicle error carries the vehicle (MAVLink system id) it is about. :class:`ExitCode`
is how an outcome reaches the shell: each command documents which of them it uses.
"""

from __future__ import annotations

from enum import IntEnum
from typing import NamedTuple


class ExitCode(IntEnum):
    """The exit codes of the ``tml`` commands (one number, one meaning, for all of them;
    how a run ends is one table, :class:`tml.run.endings.Ending`)."""

    OK = 0
    """Every file valid, the mission feasible, completed on every vehicle, or stopped."""
    INVALID = 1
    """A file invalid or a mission infeasible (``run``: also bad arguments)."""
    USAGE = 2
    """A usage or I/O error: bad arguments, a file that cannot be read."""
    ABORTED = 3
    """The mission was aborted (ABORT_MISSION, an infeasible action, Ctrl-C, SIGTERM, an
    abort through the service)."""
    FAILURE = 4
    """A vehicle was taken over (an operator's command, a failsafe, another ground station),
    or a vehicle or link failed: a failed action no event handled, no answer, a lost link."""


class Location(NamedTuple):
    """A place in a source file: 1-based line and column (column 0 when unknown).

    A named tuple rather than a dataclass because every model node carries one and a
    large mission has hundreds of thousands: construction cost matters.
    """

    file: str
    line: int
    column: int = 0

    def __str__(self) -> str:
        if self.column:
            return f"{self.file}:{self.line}:{self.column}"
        return f"{self.file}:{self.line}"


class TmlError(Exception):
    """Root of every error tml raises on purpose."""


class MissionError(TmlError):
    """Something is wrong with a mission file; says where."""

    def __init__(self, message: str, location: Location | None = None, code: str = "") -> None:
        self.message = message
        self.location = location
        self.code = code
        prefix = f"{location}: " if location else ""
        tag = f"{code} " if code else ""
        super().__init__(f"{prefix}{tag}{message}")


class MissionSyntaxError(MissionError):
    """The file is not well-formed, safe XML, or breaks the XML Schema."""


class MissionSemanticError(MissionError):
    """The file is valid XML but breaks a rule of the language."""


class MissionInfeasibleError(MissionError):
    """The mission cannot be flown within the vehicle's physical limits or the map."""


class TerrainError(TmlError):
    """Elevation data that cannot be used: a tile that is corrupt, truncated, of the wrong
    size or in another projection (``path``: the file, ``reason``: why), or a place the
    data does not cover or where it has a void."""

    def __init__(self, reason: str, path: str = "") -> None:
        self.reason = reason
        self.path = path
        super().__init__(f"{path}: {reason}" if path else reason)


class TerrainNotCovered(TerrainError):
    """A place outside every tile given (``tile``: the SRTM tile that would hold it), or on
    a void of the data (``tile``: the file with the void)."""

    def __init__(self, reason: str, latitude: float, longitude: float, tile: str) -> None:
        self.latitude = latitude
        self.longitude = longitude
        self.tile = tile
        super().__init__(reason)


class EngineError(TmlError):
    """The engine was asked for a change its rules do not allow (a defect in tml): the runner
    stops the run and commands every vehicle to its safe state."""


class ControlRefused(TmlError):
    """An operator's control that a run refuses now, saying why: a pause of a paused run,
    a resume of a running one, a jump the language does not allow (``code``: the
    language's diagnostic code, E240 ...)."""

    def __init__(self, message: str, code: str = "") -> None:
        super().__init__(message)
        self.code = code


class VehicleError(TmlError):
    """A vehicle or its link did not do what was asked."""

    def __init__(self, message: str, system_id: int | None = None) -> None:
        self.system_id = system_id
        who = f"vehicle {system_id}: " if system_id is not None else ""
        super().__init__(f"{who}{message}")


class CommandRejected(VehicleError):
    """A COMMAND_LONG/COMMAND_INT was answered with a result other than ACCEPTED."""

    def __init__(self, command: str, result: str, system_id: int | None = None) -> None:
        self.command = command
        self.result = result
        super().__init__(f"{command} rejected: {result}", system_id)


class VehicleTimeout(VehicleError):
    """A vehicle did not answer or did not reach a state within its time limit."""


class LinkLost(VehicleError):
    """No heartbeat from a vehicle for longer than the link's limit."""


class MissionTransferError(VehicleError):
    """A mission, fence or rally upload/download/clear failed (MISSION_ACK result or timeout).

    ``result`` is the MAV_MISSION_RESULT name or ``TIMEOUT``; ``seq`` the item the transfer
    was at when it failed (None before any item moved).
    """

    def __init__(self, message: str, result: str = "", system_id: int | None = None,
                 seq: int | None = None) -> None:
        self.result = result
        self.seq = seq
        super().__init__(message, system_id)
