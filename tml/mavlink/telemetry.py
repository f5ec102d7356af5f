"""Per-vehicle telemetry: a tracker that folds MAVLink messages into immutable snapshots.

:class:`TelemetryTracker` is pure: ``apply(msg, now)`` reads the fields of one pymavlink
message (duck-typed, by ``get_type()``) from its own vehicle and updates the state; the
``snapshot`` is a frozen :class:`Telemetry` the interpreter can keep, compare and read
without locks while the link goes on receiving. Messages from another system id are
refused here too, as a second guard behind the link's routing.

Vehicle state (position, attitude, mode, airframe ...) is taken only from the autopilot
component (a gimbal's or a camera's HEARTBEAT says nothing of the vehicle);
detections come as NAMED_VALUE_FLOAT / NAMED_VALUE_INT from the companion computer
(component 191, MAV_COMP_ID_ONBOARD_COMPUTER): ``detections`` keeps the latest value of
each name, ``sightings`` each object reported (a NAMED_VALUE_INT: tag and number) with the
position the DEBUG_VECT of the same name and time stamp gives it (docs/simulator.md).

Link health counts the messages received and the ones missing from the gaps in each
component's sequence numbers, and tells whether the vehicle is lost: the link asks
:meth:`TelemetryTracker.check_link`, with the time, whether the last HEARTBEAT is older
than the limit; the next HEARTBEAT ends the loss.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any

from tml.mavlink.codec import mavlink
from tml.mavlink.modes import mode_name
from tml.vehicle import ARMING_REASONS

COMPANION_COMPONENT = 191
"""MAV_COMP_ID_ONBOARD_COMPUTER: where detections come from."""
ARMED_FLAG = 128
"""MAV_MODE_FLAG_SAFETY_ARMED in HEARTBEAT.base_mode."""
EKF_POSITION_FLAGS = 16 | 2 | 512
"""EKF_POS_HORIZ_ABS | EKF_VELOCITY_HORIZ | EKF_PRED_POS_HORIZ_ABS: ArduPilot can arm in GUIDED."""
EKF_CONST_POS_MODE = 128
"""The EKF holds a constant position (no GPS): whatever else it says, it has no fix to fly on."""
PREARM_CHECK = 1 << 28
"""MAV_SYS_STATUS_PREARM_CHECK in SYS_STATUS: present when the autopilot reports its
pre-arm checks, healthy when they pass (ArduPilot)."""
PREARM_PREFIXES = ARMING_REASONS
"""How ArduPilot begins the STATUSTEXTs that say why it will not arm."""
STATUS_TEXTS_KEPT = 50
MODE_CHANGES_KEPT = 20
BOOKKEEPING = frozenset({"time", "received", "lost", "boot_time", "boot_time_received",
                         "last_heartbeat", "armed_at", "disarmed_at"})
"""Snapshot fields that change with every message (or every HEARTBEAT) while the vehicle
shows the same: they do not count as a change of its :attr:`Telemetry.revision`."""
TILTED = 1.0
"""Radians of roll or pitch (57 degrees) beyond which a multicopter counts as tilted: it gets
there only in a flip (or a crash), never in controlled flight (ArduCopter's ANGLE_MAX is 30 to
45 degrees)."""

SANE: Mapping[str, Mapping[str, tuple[float, float, float]]] = MappingProxyType({
    # message: field: (scale to the unit shown, lowest, highest) -- what a vehicle can
    # report; a message with a field outside (or NaN) is ignored and counted, not taken.
    "GLOBAL_POSITION_INT": {"lat": (1e-7, -90, 90), "lon": (1e-7, -180, 180),
                            "alt": (1e-3, -1000, 100_000),
                            "relative_alt": (1e-3, -20_000, 100_000)},
    "HOME_POSITION": {"latitude": (1e-7, -90, 90), "longitude": (1e-7, -180, 180),
                      "altitude": (1e-3, -1000, 100_000)},
    "LOCAL_POSITION_NED": {"x": (1, -1e6, 1e6), "y": (1, -1e6, 1e6), "z": (1, -1e5, 2e4)},
    "ATTITUDE": {"roll": (1, -7, 7), "pitch": (1, -7, 7), "yaw": (1, -7, 7)},
    "SYS_STATUS": {"battery_remaining": (1, -1, 100)},
    "GPS_RAW_INT": {"fix_type": (1, 0, 8)},
})
"""Bounds of the values tml takes from telemetry (units after scaling: degrees, metres,
radians, percent; -1 battery is "unknown", GPS_FIX_TYPE ends at 8): a battery at 127 %, a
NaN heading, an altitude of two thousand kilometres or a fix type of 255 is a broken or
hostile sender, never the vehicle's state."""


def absurd(msg: Any) -> str | None:
    """What is absurd in ``msg`` ("SYS_STATUS.battery_remaining = 127 (not -1 to 100)"),
    by :data:`SANE`; None when every bounded field is within its bounds."""
    bounds = SANE.get(msg.get_type())
    if bounds is None:
        return None
    for name, (scale, low, high) in bounds.items():
        value = getattr(msg, name) * scale
        if not low <= value <= high:  # NaN is never within
            return f"{msg.get_type()}.{name} = {value:.6g} (not {low:g} to {high:g})"
    return None


def _airframes() -> Mapping[int, str]:
    words = {"QUADROTOR": "quadcopter", "HEXAROTOR": "hexacopter", "OCTOROTOR": "octocopter",
             "TRICOPTER": "tricopter", "COAXIAL": "coaxial", "HELICOPTER": "helicopter",
             "FIXED_WING": "fixed-wing", "GROUND_ROVER": "rover", "SURFACE_BOAT": "boat",
             "SUBMARINE": "submarine", "AIRSHIP": "airship"}
    table = {getattr(mavlink, f"MAV_TYPE_{name}"): word for name, word in words.items()}
    # Every VTOL kind, those MAVLink still calls "reserved" included.
    table.update({number: "vtol" for number, entry in mavlink.enums["MAV_TYPE"].items()
                  if entry.name.startswith("MAV_TYPE_VTOL_")})
    return MappingProxyType(table)


AIRFRAMES = _airframes()
"""HEARTBEAT.type (MAV_TYPE) -> airframe class, a word of :data:`tml.language.kinds.VEHICLE_TYPES`.

Types that are not vehicles (GCS, gimbal, camera ...) and generic ones are left out.
"""


@dataclass(frozen=True)
class GlobalPosition:
    """WGS84 latitude/longitude in degrees, altitude above mean sea level and above home (m)."""

    latitude: float
    longitude: float
    altitude: float
    relative_altitude: float = 0.0


@dataclass(frozen=True)
class StatusText:
    """A STATUSTEXT: severity (MAV_SEVERITY, 0 worst) and text, with the time it arrived."""

    time: float
    severity: int
    text: str


@dataclass(frozen=True)
class Sighting:
    """An object the companion computer reported: when last, and where if it said."""

    time: float
    position: tuple[float, float, float] | None = None
    """North, east, up in metres from home."""


@dataclass(frozen=True)
class Telemetry:
    """What is known of one vehicle at ``time`` (None: not reported yet)."""

    system_id: int
    time: float = 0.0
    vehicle_type: int | None = None
    autopilot: int | None = None
    mode: str = ""
    armed: bool = False
    position: GlobalPosition | None = None
    local_position: tuple[float, float, float] | None = None
    """North, east, down in metres from the EKF origin (LOCAL_POSITION_NED)."""
    home: GlobalPosition | None = None
    attitude: tuple[float, float, float] | None = None
    """Roll, pitch, yaw in radians."""
    velocity: tuple[float, float, float] | None = None
    """North, east, down in m/s."""
    battery_voltage: float | None = None
    battery_remaining: int | None = None
    """Percent; None when the vehicle does not know."""
    landed_state: int | None = None
    """MAV_LANDED_STATE: 1 on ground, 2 in air, 3 taking off, 4 landing."""
    gps_fix: int | None = None
    satellites: int | None = None
    ekf_flags: int | None = None
    sensors_present: int | None = None
    """SYS_STATUS onboard_control_sensors_present (MAV_SYS_STATUS_SENSOR bits)."""
    sensors_health: int | None = None
    boot_time: float | None = None
    """Seconds since the vehicle booted (time_boot_ms of its latest message that has one)."""
    boot_time_received: float | None = None
    """When (the link's clock) ``boot_time`` arrived."""
    mission_current: int | None = None
    items_reached: tuple[int, ...] = ()
    status_texts: tuple[StatusText, ...] = ()
    status_text_count: int = 0
    """STATUSTEXTs received since the link opened (the last ``status_texts`` are kept)."""
    mode_changes: tuple[tuple[float, str], ...] = ()
    """(arrival time, mode) of the latest HEARTBEATs that showed a new mode, oldest first."""
    tilted_at: float | None = None
    """Arrival time of the latest ATTITUDE beyond :data:`TILTED` in roll or pitch."""
    armed_at: float | None = None
    """Arrival time of the latest HEARTBEAT showing the vehicle armed."""
    disarmed_at: float | None = None
    """Arrival time of the latest HEARTBEAT showing the vehicle disarmed."""
    detections: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))
    """The latest NAMED_VALUE of each name from the companion computer."""
    sightings: Mapping[tuple[str, int], Sighting] = field(
        default_factory=lambda: MappingProxyType({}))
    """Each object the companion computer reported, by (tag, number), e.g. ("MARKER", 7)."""
    last_heartbeat: float | None = None
    link_lost: bool = False
    """True while no HEARTBEAT has come for longer than the link's limit."""
    received: int = 0
    lost: int = 0
    rejected: int = 0
    """Messages ignored for an absurd value (:data:`SANE`)."""
    rejected_last: str = ""
    """What was absurd in the last of them."""
    revision: int = 0
    """Counts the messages that changed what the vehicle shows (:data:`BOOKKEEPING` aside):
    equal revisions, equal state, so a reader need not look again (the link's ``on_change``)."""

    @property
    def position_ready(self) -> bool:
        """True once the EKF reports an absolute horizontal position (arming is possible)."""
        flags = self.ekf_flags or 0
        return flags & EKF_POSITION_FLAGS == EKF_POSITION_FLAGS and not flags & EKF_CONST_POS_MODE

    @property
    def prearm_ok(self) -> bool | None:
        """Whether the autopilot's pre-arm checks pass (None: it does not say, or not yet)."""
        if self.sensors_present is None or not self.sensors_present & PREARM_CHECK:
            return None
        return bool((self.sensors_health or 0) & PREARM_CHECK)

    @property
    def prearm_text(self) -> str:
        """The autopilot's latest reason not to arm ("PreArm: ..."), "" if none was said."""
        for text in reversed(self.status_texts):
            if text.text.startswith(PREARM_PREFIXES):
                return text.text
        return ""

    @property
    def loss(self) -> float:
        """Fraction of this vehicle's messages that never arrived (from sequence gaps)."""
        total = self.received + self.lost
        return self.lost / total if total else 0.0

    @property
    def airframe(self) -> str:
        """The airframe class from the HEARTBEAT type ("quadcopter" ...), "" if unknown."""
        return "" if self.vehicle_type is None else AIRFRAMES.get(self.vehicle_type, "")

    def mode_shown_since(self, mode: str, since: float) -> bool:
        """True if a HEARTBEAT that arrived after ``since`` showed ``mode`` (or shows it now)."""
        return self.mode == mode or any(when > since and name == mode
                                        for when, name in self.mode_changes)

    def heartbeat_age(self, now: float) -> float:
        """Seconds since the last HEARTBEAT (infinite if none yet)."""
        return float("inf") if self.last_heartbeat is None else now - self.last_heartbeat


def _copy(snapshot: Telemetry, changes: Mapping[str, Any]) -> Telemetry:
    """A copy of ``snapshot`` with ``changes``, as dataclasses.replace makes it but without
    running __init__ over every field: this runs for most messages of every vehicle (a
    listener's snapshot of a message that changed only the counts, too)."""
    new = object.__new__(Telemetry)
    new.__dict__.update(snapshot.__dict__)
    new.__dict__.update(changes)
    return new


class TelemetryTracker:
    """Folds one vehicle's messages into :class:`Telemetry` snapshots."""

    def __init__(self, system_id: int, autopilot_component: int = 1,
                 companion_component: int = COMPANION_COMPONENT) -> None:
        self.autopilot_component = autopilot_component
        self.companion_component = companion_component
        self._snapshot = Telemetry(system_id)
        self._counted: tuple[float, int, int] | None = None  # (time, received, lost) not in it
        self.arrived: dict[str, float] = {}
        """When each kind of message last came from the autopilot (the link's clock)."""
        self._last_seq: dict[int, int] = {}
        self._named: tuple[str, int, int] | None = None  # (name, time_boot_ms, number)

    @property
    def snapshot(self) -> Telemetry:
        """What is known now. A message that changes nothing but the link's counts (a
        mission request, an ACK) is only counted; the snapshot takes the counts when it
        is next read, so the link builds no snapshot per item of a mission transfer."""
        if self._counted is not None:
            now, received, lost = self._counted
            self._snapshot = _copy(self._snapshot, {"time": now, "received": received,
                                                    "lost": lost})
            self._counted = None
        return self._snapshot

    @property
    def revision(self) -> int:
        """The snapshot's :attr:`Telemetry.revision` (the counts not yet taken in change
        nothing of it): safe to read from any thread without the link's lock."""
        return self._snapshot.revision

    def apply(self, msg: Any, now: float) -> bool:
        """Fold ``msg`` in; returns whether it was this vehicle's (and so changed the
        snapshot, if only its time and counts)."""
        # Runs for every message of every vehicle: written for speed (one get_type, no
        # generator), which is a good part of what reading a fleet costs.
        current = self._snapshot
        if msg.get_srcSystem() != current.system_id:
            return False
        component = msg.get_srcComponent()
        received, lost = self._count(component, msg.get_seq())
        changes: dict[str, Any] = {}
        if component == self.autopilot_component:
            kind = msg.get_type()
            if kind in SANE:
                wrong = absurd(msg)
                if wrong is not None:  # ignored whole: counted, the state kept
                    self._snapshot = replace(current, time=now, received=received,
                                             lost=lost, rejected=current.rejected + 1,
                                             rejected_last=wrong)
                    self._counted = None
                    return True
            self.arrived[kind] = now
            changes = self._vehicle_state(kind, msg, now)
            boot_ms = getattr(msg, "time_boot_ms", None)
            if boot_ms is not None:
                changes["boot_time"], changes["boot_time_received"] = boot_ms / 1000, now
        elif component == self.companion_component:
            changes = self._detection(msg, now)
        if changes:
            fields, shows_new = current.__dict__, False
            for name, value in changes.items():
                if name not in BOOKKEEPING and fields[name] != value:
                    shows_new = True
                    break
            if shows_new:
                changes["revision"] = current.revision + 1
            changes["time"], changes["received"], changes["lost"] = now, received, lost
            self._snapshot = _copy(current, changes)
            self._counted = None
        else:
            self._counted = (now, received, lost)
        return True

    def check_link(self, now: float, lost_after: float) -> bool:
        """Mark the vehicle lost if its last HEARTBEAT is older than ``lost_after`` seconds.

        Returns whether that changed the snapshot (a HEARTBEAT clears the mark in
        :meth:`apply`).
        """
        lost = self._snapshot.heartbeat_age(now) > lost_after
        if lost == self._snapshot.link_lost:
            return False
        current = self.snapshot
        self._snapshot = replace(current, link_lost=lost, revision=current.revision + 1)
        return True

    def _count(self, component: int, seq: int) -> tuple[int, int]:
        """(received, lost) with this message counted."""
        last = self._last_seq.get(component)
        self._last_seq[component] = seq
        gap = 0 if last is None else (seq - last - 1) % 256
        counted = self._counted
        received, lost = ((self._snapshot.received, self._snapshot.lost) if counted is None
                          else counted[1:])
        return received + 1, lost + gap

    def _vehicle_state(self, kind: str, msg: Any, now: float) -> dict[str, Any]:
        s = self._snapshot
        if kind == "HEARTBEAT":
            mode = mode_name(msg.type, msg.autopilot, msg.base_mode, msg.custom_mode)
            changes = s.mode_changes if mode == s.mode else (
                (*s.mode_changes, (now, mode))[-MODE_CHANGES_KEPT:])
            armed = bool(msg.base_mode & ARMED_FLAG)
            return {"vehicle_type": msg.type, "autopilot": msg.autopilot,
                    "armed": armed, "last_heartbeat": now, "link_lost": False, "mode": mode,
                    "mode_changes": changes, "armed_at" if armed else "disarmed_at": now}
        if kind == "GLOBAL_POSITION_INT":
            return {"position": GlobalPosition(msg.lat / 1e7, msg.lon / 1e7, msg.alt / 1000,
                                               msg.relative_alt / 1000),
                    "velocity": (msg.vx / 100, msg.vy / 100, msg.vz / 100)}
        if kind == "LOCAL_POSITION_NED":
            return {"local_position": (msg.x, msg.y, msg.z)}
        if kind == "HOME_POSITION":
            return {"home": GlobalPosition(msg.latitude / 1e7, msg.longitude / 1e7,
                                           msg.altitude / 1000)}
        if kind == "ATTITUDE":
            tilted = max(abs(msg.roll), abs(msg.pitch)) > TILTED
            return {"attitude": (msg.roll, msg.pitch, msg.yaw),
                    "tilted_at": now if tilted else s.tilted_at}
        if kind == "SYS_STATUS":
            remaining = msg.battery_remaining
            return {"battery_voltage": msg.voltage_battery / 1000,
                    "battery_remaining": None if remaining < 0 else remaining,
                    "sensors_present": msg.onboard_control_sensors_present,
                    "sensors_health": msg.onboard_control_sensors_health}
        if kind == "EXTENDED_SYS_STATE":
            return {"landed_state": msg.landed_state}
        if kind == "GPS_RAW_INT":
            return {"gps_fix": msg.fix_type, "satellites": msg.satellites_visible}
        if kind == "EKF_STATUS_REPORT":
            return {"ekf_flags": msg.flags}
        if kind == "MISSION_CURRENT":
            return {"mission_current": msg.seq}
        if kind == "MISSION_ITEM_REACHED":
            return {"items_reached": (*s.items_reached, msg.seq)}
        if kind == "STATUSTEXT":
            text = StatusText(now, msg.severity, _text(msg.text))
            return {"status_texts": (*s.status_texts, text)[-STATUS_TEXTS_KEPT:],
                    "status_text_count": s.status_text_count + 1}
        return {}

    def _detection(self, msg: Any, now: float) -> dict[str, Any]:
        kind = msg.get_type()
        if kind == "DEBUG_VECT":
            # Where the object just named is: same name, same time stamp.
            name = _text(msg.name)
            if self._named is None or self._named[:2] != (name, msg.time_usec // 1000):
                return {}
            return self._sighted((name, self._named[2]), Sighting(now, (msg.x, msg.y, msg.z)))
        if kind not in ("NAMED_VALUE_FLOAT", "NAMED_VALUE_INT"):
            return {}
        name = _text(msg.name)
        detections = dict(self._snapshot.detections)
        detections[name] = msg.value
        changes: dict[str, Any] = {"detections": MappingProxyType(detections)}
        if kind == "NAMED_VALUE_INT":
            self._named = (name, msg.time_boot_ms, msg.value)
            known = self._snapshot.sightings.get((name, msg.value))
            changes.update(self._sighted((name, msg.value),
                                         Sighting(now, known.position if known else None)))
        return changes

    def _sighted(self, key: tuple[str, int], sighting: Sighting) -> dict[str, Any]:
        sightings = dict(self._snapshot.sightings)
        sightings[key] = sighting
        return {"sightings": MappingProxyType(sightings)}


def _text(value: str | bytes) -> str:
    # pymavlink gives char arrays as str, or bytes when they are not valid UTF-8.
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    return value.rstrip("\x00")
