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

*A new boot heard late.* An autopilot heard again after an outage (a SITL killed and
started again and dialled again, a radio out of range while it rebooted) may have run its
new boot long enough that its clock is near, or past, where the old boot's stood: an
ArduPilot SITL at a speed-up of 10 lives 10 s for each second of the outage, and may stream
nothing for seconds after it is dialled again. Its stamps then never stay :data:`SLACK` s
behind for long, and meanwhile the silent vehicle's clock is taken to age (the action in
progress times out on it). What tells it is the autopilot's own word that it is booting
(:meth:`RebootWatch.boot_sign`: ArduPilot's HEARTBEAT ``system_status`` BOOT, and the
STATUSTEXTs it sends only while it starts, :func:`is_boot_text`), taken from a boot past
its own start (:data:`BOOTED_AFTER`: a boot's first seconds say it of themselves). That
word is a new boot at once when a stamp below the old boot's highest came just before it.
When it is the first thing heard after an outage (no stamp for :data:`OUTAGE` s), a
second word at least :data:`WORD_APART` s later makes it a new boot before any stamp
(a restarted ArduPilot says BOOT in each HEARTBEAT of its first seconds, and its start-up
texts), unless a HEARTBEAT between them said armed: a rebooted autopilot is disarmed, so
one forged HEARTBEAT saying BOOT after an outage is answered by the flying autopilot's next
HEARTBEAT, and believes nothing. In every case the next stamp decides: a new boot when it
is below the old boot's highest, or, after an outage, below where the old boot's clock
should be by now: its highest stamp aged by the local time since, at half the rate its
stamps rose over the last
:data:`RATE_WINDOW` s (the speed-up is not known, and a SITL starved of CPU lives slower
than it did); the old boot going on when it is not, and the word forgotten. Without that
word nothing changes: a vehicle that merely runs slow, a link that delays, reorders or
repeats messages, says nothing of a boot, and its stamps are judged as above.

Whether the vehicle was armed when it rebooted is told from its HEARTBEATs of the old boot
(:meth:`RebootWatch.heartbeat`): the rebooted autopilot says disarmed wherever it is. Armed
within :data:`ARMED_WITHIN` s of the old boot's last stamp, it rebooted armed -- for an
aircraft, in the air or about to be: a catastrophe the ground station can only report.
"""

from __future__ import annotations

import re
from collections import deque
from dataclasses import dataclass

SLACK = 1.0
"""Seconds a stamp may fall behind the highest seen without meaning a reboot (a message
delayed or reordered on the way, a clock that is stepped)."""
AGREE = 0.9
"""Seconds (local time) over which every stamp must stay in the new boot before the reboot is
believed: about two of ArduPilot's 1 Hz stamps, ten of its 10 Hz ones."""
OUTAGE = 1.0
"""Local seconds without a stamp after which the old boot's clock is judged aged by them."""
BOOTED_AFTER = 10.0
"""Seconds of a boot's own clock after which its autopilot's word that it is booting is a
new boot's: ArduPilot says it within the first 5 s (BOOT until its set-up is done, its EKF
initialised at about 4.4 s, measured on ArduCopter SITL)."""
WORD_APART = 0.5
"""Local seconds between two words of a boot after an outage for the second to confirm the
first (ArduPilot beats at 1 Hz: its next HEARTBEAT, or a start-up text, confirms; a burst of
messages sent at once does not)."""
RATE_WINDOW = 5.0
"""Local seconds of the old boot's stamps its clock's rate is measured over."""
MIN_RATE_SPAN = 0.5
"""Local seconds two stamps must span before their rate is believed (0 before: a stamp is
then short of the old boot's clock only below its highest)."""
BOOT_TEXTS = re.compile(r"(ArduPilot Ready|Initialising ArduPilot|EKF\d IMU\d initialised)$")
"""The STATUSTEXTs ArduPilot sends only while it starts (its EKF's first initialisation, the
end of its set-up)."""
ARMED_WITHIN = 3.0
"""Seconds of the old boot's clock before its last stamp within which a HEARTBEAT saying
armed means it rebooted armed (three of ArduPilot's 1 Hz HEARTBEATs: one may be lost)."""


@dataclass(frozen=True)
class Reboot:
    """A reboot seen: the vehicle's clock went from ``before`` back to ``after`` (s);
    ``armed``: it was armed when it rebooted."""

    before: float
    after: float | None  # None: told by the autopilot's word before any stamp of the new boot
    armed: bool = False

    def __str__(self) -> str:
        back = "a new boot's: it said it was booting" if self.after is None \
            else f"{self.after:.1f} s"
        return (f"rebooted {'while armed' if self.armed else 'disarmed'} (its clock went "
                f"from {self.before:.1f} s back to {back})")


def is_boot_text(text: str) -> bool:
    """Whether an autopilot's STATUSTEXT says it is starting (:data:`BOOT_TEXTS`)."""
    return BOOT_TEXTS.match(text.strip()) is not None


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
        self._rising: deque[tuple[float, float]] = deque()  # the boot's (local, stamp) as it rose
        self._heard_at = 0.0  # local time of the boot's latest stamp
        self._booting = False  # the autopilot said it is booting since the boot's latest stamp
        self._word_at: float | None = None  # local time of a word of a boot after an outage

    def heartbeat(self, armed: bool) -> None:
        """A HEARTBEAT of the autopilot says ``armed`` (or not)."""
        if armed and self._word_at is not None:  # a rebooted autopilot says disarmed
            self._word_at, self._booting = None, False
        if armed and self._since is None and not self._booting:
            self._armed_at = self.highest

    def boot_sign(self, now: float) -> bool:
        """The autopilot says it is booting (its HEARTBEAT's ``system_status`` BOOT, a
        STATUSTEXT of :func:`is_boot_text`) at ``now`` (local s); True when that makes a
        reboot believed (a low stamp came before the word; see the module docstring)."""
        if self.highest is None or self.highest < BOOTED_AFTER:
            return False
        if self._since is not None:
            return self._believe(*self._since)
        if now - self._heard_at >= OUTAGE:  # heard again after an outage, booting
            if self._word_at is None:
                self._word_at = now
            elif now - self._word_at >= WORD_APART:  # said again, never armed between
                return self._believe(now, None)
        self._booting = True
        return False

    def expected(self, now: float) -> float:
        """The least the old boot's clock is taken to read at ``now`` (local s) when the
        autopilot has said it is booting: see the module docstring."""
        assert self.highest is not None
        if now - self._heard_at < OUTAGE or not self._rising:
            return self.highest
        first_at, first = self._rising[0]
        last_at = self._rising[-1][0]
        if last_at - first_at < MIN_RATE_SPAN:
            return self.highest
        rate = max(0.0, (self.highest - first) / (last_at - first_at))
        return self.highest + (now - last_at) * rate / 2

    def seen(self, stamp: float, now: float) -> bool:
        """A message stamped ``stamp`` (s since boot) arrived at ``now`` (local s); True
        when that makes a reboot believed (once per reboot)."""
        if self.highest is not None and self._booting and stamp < self.expected(now):
            return self._believe(now, stamp)  # a new boot, said so
        if self.highest is None or stamp >= self.highest - SLACK:
            self._since = None  # the old boot goes on: a low stamp before was stray
            self._booting, self._word_at = False, None  # ... and so was a word of a boot
            self._heard_at = now
            if self.highest is None or stamp > self.highest:
                self._rose(stamp, now)
            return False
        if self._since is None:
            self._since = (now, stamp)
            return False
        if now - self._since[0] >= AGREE:
            first_at, first = self._since
            self._believe(first_at, first)
            if stamp > first:
                self._rose(stamp, now)
            return True
        return False

    def _rose(self, stamp: float, now: float) -> None:
        self.highest, self._heard_at = stamp, now
        self._rising.append((now, stamp))
        while len(self._rising) > 2 and now - self._rising[0][0] > RATE_WINDOW:
            self._rising.popleft()

    def _believe(self, now: float, stamp: float | None) -> bool:
        """A new boot, heard first at ``now`` stamped ``stamp`` (None: no stamp yet): told,
        and followed."""
        assert self.highest is not None
        armed = self._armed_at is not None and self._armed_at >= self.highest - ARMED_WITHIN
        self.reboot = Reboot(self.highest, stamp, armed)
        self.count += 1
        # The new boot from here on: its stamps, and a next reboot's fall from them.
        self._since, self._armed_at, self._booting, self._word_at = None, None, False, None
        self._rising.clear()
        if stamp is None:
            self.highest = None  # its first stamp starts it
        else:
            self._rose(stamp, now)
        return True
