"""ArduCopter's arming checks as the simulated vehicle runs them, and when it reports them.

ArduCopter SITL (4.7, ``copter.parm``, measured at speed-up 10) boots for 2.5 s
(HEARTBEAT ``system_status`` BOOT; a mode selected meanwhile is replaced by STABILIZE when
it says "ArduPilot Ready"), and is not armable at once: its checks fail in stages while the
simulated sensors and the EKF start. Retrying the arm
command every second of vehicle time from boot, the refusals were (times in vehicle s):

======================  ==================================  ===============================
until                   every mode                          modes that need a position
======================  ==================================  ===============================
2.5 s                   ``System not initialised`` (alone)
6 s                     ``EKF attitude is bad``
13.5 s                  ``Accels inconsistent``
23 s                    ``Gyros inconsistent``
the EKF origin (20 s)                                       ``AHRS: waiting for home``
the EKF uses GPS (41 s)                                     ``Need Position Estimate``
======================  ==================================  ===============================

so STABILIZE arms at about 23 s and GUIDED at about 42 s. The sensor stages keep those
times when ``SIM_EKF_GPS_TIME`` has its default (41 s) and shrink in proportion when it is
set shorter, so that cutting the start-up (``SIM_GPS_LOCKTIME=1 SIM_EKF_GPS_TIME=2``) cuts
all of it. The checks that follow (battery failsafe, fence) are the simulator's own.

Every failing check is reported, each in its own STATUSTEXT (severity CRITICAL): prefixed
``Arm:`` when an arm command runs them (answered COMMAND_ACK FAILED), ``PreArm:`` when the
vehicle reports them by itself while disarmed: every 30 s, and about 2 s after a mode
change or a disarm (ArduPilot's "report immediately", at most once every 4 s). SYS_STATUS
carries the outcome in its MAV_SYS_STATUS_PREARM_CHECK bit, healthy when they pass.
"""

from __future__ import annotations

from typing import Protocol

from sitl.modes import ModeTable

# (ArduCopter's time in s at which the check passes, its failure), in ArduCopter's order;
# the inertial sensors report one failure at a time (accelerometers before gyros).
INERTIAL_STAGES = ((13.5, "Accels inconsistent"), (23.0, "Gyros inconsistent"))
ATTITUDE_AT = (6.0, "EKF attitude is bad")
READY_AT = 2.5  # s: "ArduPilot Ready"; "System not initialised" before
EKF_GPS_DEFAULT = 41.0  # SIM_EKF_GPS_TIME's default, the time the stages are measured against
MODE_NOT_ARMABLE = "Mode not armable"  # checked at arming, not among the pre-arm checks
REPORT_PERIOD = 30.0  # s between PreArm reports (ArduPilot's PREARM_DISPLAY_PERIOD)
REPORT_SOON = 2.0  # s from a mode change or disarm to the report it brings forward
REPORT_GAP = 4.0  # s: a report brought forward never follows the last one sooner


class Armable(Protocol):
    """What the checks read from the vehicle model."""

    time: float
    mode: str
    mode_table: ModeTable  # the vehicle kind's modes: where it arms, which need a position
    armed: bool
    origin_set: bool

    @property
    def position_ok(self) -> bool: ...  # read-only: the model derives it

    def extra_arming_failures(self) -> list[str]: ...


def startup_scale(ekf_gps_time: float) -> float:
    """The factor applied to ArduCopter's start-up times for this ``SIM_EKF_GPS_TIME``."""
    return min(1.0, max(ekf_gps_time, 0.0) / EKF_GPS_DEFAULT)


def failures(v: Armable, ekf_gps_time: float) -> list[str]:
    """The checks that fail now, in ArduCopter's order (empty: armable)."""
    scale = startup_scale(ekf_gps_time)
    if v.time < READY_AT * scale:
        return ["System not initialised"]
    found = []
    if v.mode not in v.mode_table.armable:
        found.append(MODE_NOT_ARMABLE)
    inertial = [failure for passes_at, failure in INERTIAL_STAGES if v.time < passes_at * scale]
    found += inertial[:1]
    if v.time < ATTITUDE_AT[0] * scale:
        found.append(ATTITUDE_AT[1])
    if v.mode in v.mode_table.needs_position:
        if not v.origin_set:
            found.append("AHRS: waiting for home")
        elif not v.position_ok:
            found.append("Need Position Estimate")
    return found + v.extra_arming_failures()


def prearm_passes(v: Armable, ekf_gps_time: float) -> bool:
    """SYS_STATUS's pre-arm check bit: the checks pass in the present mode (armed: always)."""
    return v.armed or not [f for f in failures(v, ekf_gps_time) if f != MODE_NOT_ARMABLE]


class PrearmReports:
    """When the vehicle, disarmed, reports its failing checks as ``PreArm: ...``."""

    def __init__(self) -> None:
        self._last = 0.0
        self._soon: float | None = None

    def bring_forward(self, now: float) -> None:
        """A mode change or a disarm: report again shortly."""
        self._soon = now + REPORT_SOON

    def due(self, now: float) -> bool:
        """True when a report is due at ``now`` (and counts it as made)."""
        soon = self._soon is not None and now >= self._soon and now - self._last >= REPORT_GAP
        if soon or now - self._last >= REPORT_PERIOD:
            self._last, self._soon = now, None
            return True
        return False
