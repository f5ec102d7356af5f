"""The vehicle's failsafes, as ArduCopter raises them and what each one does.

Checked once per control tick (:meth:`Failsafes.check`), in this order: the battery (low
and critical levels, each latched until a reboot, as ArduPilot's battery monitor does),
the ground station (``FS_GCS_ENABLE``: no HEARTBEAT from ``MAV_GCS_SYSID`` for
``FS_GCS_TIMEOUT`` s, cleared when it is heard again), the EKF (the GPS lost: LAND where
the vehicle is, in a mode that needs the position) and the fence (``FENCE_ENABLE``, its
``FENCE_ACTION``, cleared once back inside). Each raised failsafe says so with a
STATUSTEXT in ArduCopter's words and, while armed, takes its action through the vehicle's
own mode changes (:meth:`Failsafes.act`). The vehicle reads :attr:`Failsafes.active` for
its arming checks and HEARTBEAT's system status.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl import fence

if TYPE_CHECKING:
    from sitl.model import VehicleModel

M = mavlink


class Failsafes:
    """The failsafes raised on one vehicle (``active``: "battery", "battery critical",
    "gcs", "ekf", "fence") and when its ground station was last heard (``gcs_seen``)."""

    def __init__(self) -> None:
        self.active: set[str] = set()
        self.gcs_seen: float | None = None  # None: no ground station heard yet
        self._low_voltage_since: float | None = None

    def check(self, v: VehicleModel) -> None:
        """Raise (and clear) the failsafes whose conditions changed on ``v``."""
        self._battery(v)
        active, params = self.active, v.params
        if params["FS_GCS_ENABLE"] and self.gcs_seen is not None:
            lost = v.time - self.gcs_seen > params["FS_GCS_TIMEOUT"]
            if lost and "gcs" not in active and v.armed:
                active.add("gcs")
                v.text(M.MAV_SEVERITY_CRITICAL, "GCS Failsafe")
                action = round(params["FS_GCS_ENABLE"])
                if not (action == 2 and v.mode == "AUTO"):
                    # ArduCopter's failsafe_gcs_on_event: 4 (SmartRTL or LAND; no SmartRTL
                    # here) and 5 land, every other value returns (RTL, LAND if it cannot).
                    self.act(v, 1 if action in (4, 5) else 2)
            elif not lost and "gcs" in active:
                active.discard("gcs")
                v.text(M.MAV_SEVERITY_CRITICAL, "GCS Failsafe Cleared")
        gps_loss_at = v.faults.gps_loss_at  # v._gps_lost, without the call
        if gps_loss_at is not None and v.time >= gps_loss_at and "ekf" not in active:
            active.add("ekf")
            v.text(M.MAV_SEVERITY_CRITICAL, "GPS Glitch or Compass error")
            if v.armed and not v.landed and v.mode in v.mode_table.needs_position:
                v.text(M.MAV_SEVERITY_CRITICAL, "EKF Failsafe: changed to LAND Mode")
                v.land_here()
        if params["FENCE_ENABLE"] and v.armed and not v.landed:
            breach = v.geofence.breach(v.position, params, v.home_local())
            if breach and "fence" not in active:
                active.add("fence")
                # A notice, as ArduCopter says it (AC_Fence), and "Fence breach cleared"
                # once back inside.
                v.text(M.MAV_SEVERITY_NOTICE, fence.BREACH_TEXTS[breach])
                action = round(params["FENCE_ACTION"])
                if action and v.mode not in ("RTL", "LAND"):
                    self.act(v, {1: 2, 2: 1, 3: 2, 4: 4, 5: 2}.get(action, 2))
            elif not breach and "fence" in active:
                active.discard("fence")
                v.text(M.MAV_SEVERITY_NOTICE, "Fence breach cleared")

    def _battery(self, v: VehicleModel) -> None:
        """Raise the low and critical battery failsafes as their conditions arise.

        Each level latches, as ArduPilot's battery monitor does until a reboot: a pack
        recharged on its pad reports its charge again but still refuses arming
        ("PreArm: Battery failsafe") once a failsafe was raised.
        """
        p, battery = v.params, v.battery
        voltage = battery.voltage
        if voltage < p["BATT_LOW_VOLT"]:
            self._low_voltage_since = self._low_voltage_since or v.time
        else:
            self._low_voltage_since = None
        remaining_mah = battery.capacity_mah - battery.consumed_mah
        critical = battery.failed or (0 < voltage < p["BATT_CRT_VOLT"])
        low = critical or (
            self._low_voltage_since is not None
            and v.time - self._low_voltage_since >= p["BATT_LOW_TIMER"]
        ) or (p["BATT_LOW_MAH"] > 0 and remaining_mah < p["BATT_LOW_MAH"])
        if low and "battery" not in self.active:
            self._raise_battery(v, "battery", "low", voltage, p["BATT_FS_LOW_ACT"])
        if critical and "battery critical" not in self.active:
            self._raise_battery(v, "battery critical", "critical", voltage,
                                p["BATT_FS_CRT_ACT"])

    def _raise_battery(self, v: VehicleModel, level: str, word: str, voltage: float,
                       action: float) -> None:
        self.active.add(level)
        v.text(M.MAV_SEVERITY_CRITICAL,
               f"Battery 1 is {word} {voltage:.2f}V used {v.battery.consumed_mah:.0f} mAh")
        if v.armed:
            self.act(v, round(action))

    @staticmethod
    def act(v: VehicleModel, action: int) -> None:
        """ArduCopter's failsafe actions: 1 land, 2/3/4 RTL (land if RTL fails), 5 disarm."""
        if not v.armed:
            return
        if v.landed:
            v.disarm()
        elif action == 1:
            v.set_mode("LAND")
        elif action in (2, 3, 4):
            if not v.set_mode("RTL"):
                v.set_mode("LAND")
        elif action == 5:
            v.disarm()
