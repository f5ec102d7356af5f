"""A reboot of the autopilot, told from the ``time_boot_ms`` of its messages.

An autopilot that reboots (a power glitch, a watchdog, a crash, a reboot command, the
process of a SITL killed and started again) starts its clock again from zero: the
``time_boot_ms`` of its messages goes back. It comes back disarmed, in its first mode
(ArduCopter: STABILIZE), with nothing of what a ground station had asked of it. A ground
station that does not see the reboot waits for the action in progress to time out; one that
does says so at once.

:class:`RebootWatch` is pure: it is fed each stamp of the autopilot's messages with the
local time it arrived. A stamp more than :data:`SLACK` s behind the highest one seen starts
a new boot only when every stamp for :data:`AGREE` s stays behind: one stray or forged
message (without signing any client on the link can send one as the autopilot, and a
message delayed on the way arrives late) is answered by the real autopilot's next stamp,
and believes nothing. After a reboot the watch follows the new boot, and tells the next
reboot too (:attr:`RebootWatch.count`): a vehicle kept open across runs (``tml serve``) is
judged by each run on the reboots during it.

Whether the vehicle was armed when it rebooted is told from its HEARTBEATs of the old boot
(:meth:`RebootWatch.heartbeat`): the rebooted autopilot says disarmed wherever it is. Armed
within :data:`ARMED_WITHIN` s of the old boot's last stamp, it rebooted armed -- for an
aircraft, in the air or about to be: a catastrophe the ground station can only report.
"""

from __future__ import annotations

from dataclasses import dataclass

SLACK = 1.0
"""Seconds a stamp may fall behind the highest seen without meaning a reboot (a message
delayed or reordered on the way, a clock that is stepped)."""
AGREE = 0.9
"""Seconds (local time) over which every stamp must stay in the new boot before the reboot is
believed: about two of ArduPilot's 1 Hz stamps, ten of its 10 Hz ones."""
ARMED_WITHIN = 3.0
"""Seconds of the old boot's clock before its last stamp within which a HEARTBEAT saying
armed means it rebooted armed (three of ArduPilot's 1 Hz HEARTBEATs: one may be lost)."""


@dataclass(frozen=True)
class Reboot:
    """A reboot seen: the vehicle's clock went from ``before`` back to ``after`` (s);
    ``armed``: it was armed when it rebooted."""

    before: float
    after: float
    armed: bool = False

    def __str__(self) -> str:
        return (f"rebooted {'while armed' if self.armed else 'disarmed'} (its clock went "
                f"from {self.before:.1f} s back to {self.after:.1f} s)")


class RebootWatch:
    """Tells a reboot from the autopilot's boot-time stamps; see the module docstring."""

    def __init__(self) -> None:
        self.highest: float | None = None
        self.reboot: Reboot | None = None
        """The latest reboot seen (None: none)."""
        self.count = 0
        """Reboots seen so far."""
        self._since: tuple[float, float] | None = None  # (local time, stamp) of the first low one
        self._armed_at: float | None = None  # the highest stamp when a HEARTBEAT said armed

    def heartbeat(self, armed: bool) -> None:
        """A HEARTBEAT of the autopilot says ``armed`` (or not)."""
        if armed and self._since is None:
            self._armed_at = self.highest

    def seen(self, stamp: float, now: float) -> bool:
        """A message stamped ``stamp`` (s since boot) arrived at ``now`` (local s); True
        when that makes a reboot believed (once per reboot)."""
        if self.highest is None or stamp >= self.highest - SLACK:
            self._since = None  # the old boot goes on: a low stamp before was stray
            self.highest = stamp if self.highest is None else max(self.highest, stamp)
            return False
        if self._since is None:
            self._since = (now, stamp)
            return False
        if now - self._since[0] >= AGREE:
            armed = self._armed_at is not None and \
                self._armed_at >= self.highest - ARMED_WITHIN
            self.reboot = Reboot(self.highest, self._since[1], armed)
            self.count += 1
            # The new boot from here on: its stamps, and a next reboot's fall from them.
            self.highest, self._since, self._armed_at = stamp, None, None
            return True
        return False
