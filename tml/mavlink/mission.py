"""The MAVLink mission protocol as a pure state machine (no sockets, no clock).

Theory of operation
-------------------
A transfer (:class:`Upload`, :class:`Download` or :class:`Clear`) talks to one vehicle about
one mission type (mission, fence or rally). It never touches a socket or reads a clock, in
the manner of h11: the caller

* calls ``start(now)`` and sends the messages it returns,
* feeds every mission-protocol message from that vehicle to ``receive(msg, now)`` and sends
  what comes back,
* calls ``tick(now)`` no later than ``deadline`` and sends what comes back (retransmissions),

until ``done`` is true; then ``items`` (download) holds the result, or ``error`` holds a
:class:`~tml.errors.MissionTransferError` naming the MISSION_ACK result or the timeout.

Messages are plain frozen dataclasses (:class:`MissionItem`, :class:`MissionCount`, ...);
``tml.mavlink.codec`` translates them to and from pymavlink, so this module and its callers
(the interpreter compiles actions to :class:`MissionItem`) never import pymavlink.

Timeouts and retries are per message, as the MAVLink mission protocol recommends and
QGroundControl's PlanManager does: the opening message (MISSION_COUNT,
MISSION_REQUEST_LIST, MISSION_CLEAR_ALL) waits :data:`DEFAULT_TIMEOUT` (1500 ms) for its
answer, each item exchange :data:`ITEM_TIMEOUT` (250 ms); a message left unanswered is
retried on its own timeout up to :data:`RETRIES` (5) times, then the transfer fails with a
:class:`~tml.errors.MissionTransferError` naming the item (``seq``) and what went
unanswered. Any answer from the vehicle about the transfer starts the count over (the
mission protocol's "no response"): a vehicle that answers without moving on ends the
transfer itself (ArduPilot cancels an upload after 8 s without a new item).

A retry is a burst of :data:`COPIES` (3) messages, since the losses of separate frames are
independent: one round trip through 30 % loss each way succeeds with probability 0.49, so
six single attempts all fail with probability 0.51**6 = 1.8 % per item (a 100-item transfer
would fail five times in six); a burst of three brings the exchange's failure to
0.51 * 0.51**15 = 2e-5. A clean link never retries and sees no burst.
docs/reliability.md ("Mission transfer") has the analysis and the measured rates.

A request lost on its way is the hard case for an upload: the vehicle holds the item and
waits for the next, repeating the item cannot help (ArduPilot answers a repeat with
MISSION_ACK INVALID_SEQUENCE, which therefore ends nothing), and ArduPilot asks again only
once a second. So an upload's burst is the last item asked for and the two after it;
vehicles accept the item they expect whether asked for or not, and answer the others with
INVALID_SEQUENCE. When the final ACK is lost, ArduPilot never repeats it: the upload ends
``unconfirmed`` and a read-back settles it (``Vehicle.upload`` does).

Requests may come out of order or twice; each is answered with the item asked for. The
legacy MISSION_REQUEST (ArduPilot asks with it) is answered with MISSION_ITEM_INT like
MISSION_REQUEST_INT. ArduPilot keeps home in mission item 0 and overwrites it:
:func:`with_home_placeholder` shifts N real items to seq 1..N behind a placeholder.

A vehicle reads items back in its own storage form. :func:`read_back_differences` compares
a read-back with what was sent, through a *form* that says what each field should read
back as: :func:`exact_form` (every field as sent, what other autopilots are held to) or
:func:`ardupilot_form` (ArduPilot keeps only some params of each command, in C integer
types, and positions in whole centimetres with the frame's family). It returns every
difference as an :class:`ItemDifference` naming the item, the field and both values.
"""

from __future__ import annotations

import enum
import math
import struct
import types
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TypedDict, Unpack

from tml.actions.items import LOITER_TURNS_MAX
from tml.errors import MissionTransferError

DEFAULT_TIMEOUT = 1.5
"""Seconds to wait for the answer to MISSION_COUNT / MISSION_REQUEST_LIST / CLEAR_ALL."""
ITEM_TIMEOUT = 0.25
"""Seconds to wait for the next request or item once items flow."""
RETRIES = 5
"""Retries of a message left unanswered before the transfer fails."""
COPIES = 3
"""Copies of a message in each retry (a burst: losses of separate frames are independent)."""


class MissionType(enum.IntEnum):
    """MAV_MISSION_TYPE: which of the vehicle's lists a transfer is about."""

    MISSION = 0
    FENCE = 1
    RALLY = 2
    ALL = 255


class MissionResult(enum.IntEnum):
    """MAV_MISSION_RESULT, the result field of MISSION_ACK (names as in the MAVLink XML)."""

    MAV_MISSION_ACCEPTED = 0
    MAV_MISSION_ERROR = 1
    MAV_MISSION_UNSUPPORTED_FRAME = 2
    MAV_MISSION_UNSUPPORTED = 3
    MAV_MISSION_NO_SPACE = 4
    MAV_MISSION_INVALID = 5
    MAV_MISSION_INVALID_PARAM1 = 6
    MAV_MISSION_INVALID_PARAM2 = 7
    MAV_MISSION_INVALID_PARAM3 = 8
    MAV_MISSION_INVALID_PARAM4 = 9
    MAV_MISSION_INVALID_PARAM5_X = 10
    MAV_MISSION_INVALID_PARAM6_Y = 11
    MAV_MISSION_INVALID_PARAM7 = 12
    MAV_MISSION_INVALID_SEQUENCE = 13
    MAV_MISSION_DENIED = 14
    MAV_MISSION_OPERATION_CANCELLED = 15


def result_name(result: int) -> str:
    """The MAV_MISSION_RESULT name of ``result`` (``MAV_MISSION_RESULT_<n>`` if unknown)."""
    try:
        return MissionResult(result).name
    except ValueError:
        return f"MAV_MISSION_RESULT_{result}"


@dataclass(frozen=True)
class MissionItem:
    """One MISSION_ITEM_INT, as plain data.

    ``x``/``y`` are latitude/longitude in degrees * 1e7 for global frames (metres * 1e4
    for local ones, as the MAVLink message says); ``z`` is altitude in metres.
    """

    seq: int
    frame: int
    command: int
    current: int = 0
    autocontinue: int = 1
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: int = 0
    y: int = 0
    z: float = 0.0
    mission_type: int = MissionType.MISSION


@dataclass(frozen=True)
class MissionCount:
    """MISSION_COUNT: the sender announces how many items follow."""

    count: int
    mission_type: int = MissionType.MISSION


@dataclass(frozen=True)
class MissionRequest:
    """MISSION_REQUEST_INT, or the legacy MISSION_REQUEST when ``legacy`` is true."""

    seq: int
    mission_type: int = MissionType.MISSION
    legacy: bool = False


@dataclass(frozen=True)
class MissionRequestList:
    """MISSION_REQUEST_LIST: start of a download."""

    mission_type: int = MissionType.MISSION


@dataclass(frozen=True)
class MissionClearAll:
    """MISSION_CLEAR_ALL."""

    mission_type: int = MissionType.MISSION


@dataclass(frozen=True)
class MissionAck:
    """MISSION_ACK: end of a transfer, with a MAV_MISSION_RESULT."""

    result: int
    mission_type: int = MissionType.MISSION


MissionMessage = (
    MissionItem | MissionCount | MissionRequest | MissionRequestList | MissionClearAll | MissionAck
)
"""Any message of the mission protocol, as plain data."""


@dataclass(frozen=True)
class Progress:
    """How far a transfer is: ``done`` of ``total`` items (total 0 until known)."""

    done: int
    total: int


class TransferOptions(TypedDict, total=False):
    """The options every transfer takes (see :class:`Transfer`)."""

    system_id: int | None
    timeout: float
    item_timeout: float
    retries: int
    copies: int


class Transfer:
    """What upload, download and clear share: the timer, the retry count, the outcome."""

    operation = "transfer"
    inputs: type | types.UnionType = MissionMessage
    """The plain messages a transfer takes (what a link feeds it)."""

    def __init__(
        self,
        mission_type: int = MissionType.MISSION,
        *,
        system_id: int | None = None,
        timeout: float = DEFAULT_TIMEOUT,
        item_timeout: float = ITEM_TIMEOUT,
        retries: int = RETRIES,
        copies: int = COPIES,
    ) -> None:
        self.mission_type = int(mission_type)
        self.copies = copies
        self.system_id = system_id
        self.timeout = timeout
        self.item_timeout = item_timeout
        self.retries = retries
        self.deadline = float("inf")
        self.error: MissionTransferError | None = None
        self.succeeded = False
        self.retransmissions = 0
        self._retried = 0
        self._last_sent: list[MissionMessage] = []

    @property
    def done(self) -> bool:
        """True once the transfer has succeeded or failed."""
        return self.succeeded or self.error is not None

    @property
    def progress(self) -> Progress:
        """Items moved so far; subclasses with items override."""
        return Progress(1 if self.succeeded else 0, 1)

    def start(self, now: float) -> list[MissionMessage]:
        """Begin the transfer; returns the messages to send."""
        return self._send(now, self._opening())

    def _opening(self) -> MissionMessage:
        raise NotImplementedError

    def receive(self, msg: MissionMessage, now: float) -> list[MissionMessage]:
        """Feed one message from the vehicle; returns the messages to send."""
        if self.done or getattr(msg, "mission_type", self.mission_type) != self.mission_type:
            return []
        self._retried = 0  # any answer: the link and the vehicle are there
        return self._handle(msg, now)

    def tick(self, now: float) -> list[MissionMessage]:
        """Advance the clock; returns a retransmission once the deadline has passed, or
        fails the transfer when the message awaiting its answer was already retried
        ``retries`` times."""
        if self.done or now < self.deadline:
            return []
        if self._retried >= self.retries:
            self._fail(self._unanswered(), "TIMEOUT")
            return []
        self._retried += 1
        self.retransmissions += 1
        self.deadline = now + self._current_timeout()
        return self._retransmission()

    def _retransmission(self) -> list[MissionMessage]:
        return list(self._last_sent) * self.copies

    def _unanswered(self) -> str:
        """Why the transfer gave up: the message left unanswered, named for the user."""
        return (f"no answer to {_name(self._last_sent)} after {self.retries} retries "
                f"{_ms(self._current_timeout())} apart")

    def _handle(self, msg: MissionMessage, now: float) -> list[MissionMessage]:
        raise NotImplementedError

    def _current_timeout(self) -> float:
        return self.timeout

    def _send(self, now: float, *msgs: MissionMessage) -> list[MissionMessage]:
        """Send ``msgs`` in answer to the vehicle: a new exchange, with its own retries."""
        self._last_sent = list(msgs)
        self._retried = 0
        self.deadline = now + self._current_timeout()
        return list(msgs)

    def _succeed(self) -> None:
        self.succeeded = True
        self.deadline = float("inf")

    def _at(self) -> int | None:
        """The item the transfer is at (None before any item moved)."""
        return None

    def _fail(self, why: str, result: str) -> None:
        kind = MissionType(self.mission_type).name.lower()
        self.error = MissionTransferError(f"{kind} {self.operation} failed: {why}", result,
                                          self.system_id, self._at())
        self.deadline = float("inf")

    def _ack_failure(self, ack: MissionAck) -> None:
        name = result_name(ack.result)
        self._fail(name, name)


_UNCONFIRMED = ("TIMEOUT", MissionResult.MAV_MISSION_ERROR.name)
"""How an upload whose every item went out can end without telling whether it landed."""


class Upload(Transfer):
    """Send ``items`` (seq 0..N-1, in order) to the vehicle."""

    operation = "upload"

    def __init__(self, items: list[MissionItem], mission_type: int = MissionType.MISSION,
                 offer_next: bool = True, **options: Unpack[TransferOptions]) -> None:
        super().__init__(mission_type, **options)
        self.offer_next = offer_next
        for index, item in enumerate(items):
            if item.seq != index:
                raise ValueError(f"item {index} has seq {item.seq}; items must be numbered 0..N-1")
        self.items = [item if item.mission_type == self.mission_type
                      else replace(item, mission_type=self.mission_type) for item in items]
        self._requested: set[int] = set()
        self._sent: set[int] = set()

    @property
    def progress(self) -> Progress:
        """Distinct items sent so far (all of them once the vehicle acknowledged)."""
        total = len(self.items)
        return Progress(total if self.succeeded else len(self._sent), total)

    @property
    def unconfirmed(self) -> bool:
        """True if every item went out but no final ACK came (ArduPilot does not resend it).

        That is silence, or MAV_MISSION_ERROR: ArduPilot's answer to an item that comes
        when it is no longer receiving, as an offer or a repeat does once the vehicle has
        stored the last item and its ACCEPTED was lost. Only reading the mission back can
        tell whether the vehicle has it all.
        """
        return (self.error is not None and self.error.result in _UNCONFIRMED
                and len(self._sent) == len(self.items) > 0)

    def _opening(self) -> MissionMessage:
        # MISSION_COUNT announces the number of items.
        return MissionCount(len(self.items), self.mission_type)

    def _current_timeout(self) -> float:
        return self.item_timeout if self._requested else self.timeout

    def _at(self) -> int | None:
        return max(self._requested) if self._requested else None

    def _unanswered(self) -> str:
        retried = f"{self.retries} retries {_ms(self._current_timeout())} apart"
        if not self._requested:
            return f"no request for item 0 after MISSION_COUNT ({len(self.items)}), {retried}"
        last = max(self._requested)
        if last == len(self.items) - 1:
            return f"no MISSION_ACK after the last item ({last}), {retried}"
        return f"no request after item {last} (of {len(self.items)}), {retried}"

    def _handle(self, msg: MissionMessage, now: float) -> list[MissionMessage]:
        if isinstance(msg, MissionRequest):
            if not 0 <= msg.seq < len(self.items):
                return []  # a request outside the mission: nothing sensible to send back
            self._requested.add(msg.seq)
            return self._send_item(now, msg.seq)
        if isinstance(msg, MissionAck):
            if msg.result == MissionResult.MAV_MISSION_INVALID_SEQUENCE and self._requested:
                # ArduPilot's answer to an item other than the one it waits for (a repeat,
                # or an offer, see _retransmission): not an end, the vehicle is still there.
                pass
            elif msg.result != MissionResult.MAV_MISSION_ACCEPTED:
                self._ack_failure(msg)
            elif len(self._requested) == len(self.items) or self._sent_last():
                self._succeed()
            # An ACCEPTED before any item went out is a late answer to an earlier transfer;
            # wait for the vehicle to go on asking.
        return []

    def _send_item(self, now: float, seq: int) -> list[MissionMessage]:
        self._sent.add(seq)
        return self._send(now, self.items[seq])

    def _sent_last(self) -> bool:
        return len(self.items) - 1 in self._sent

    def _retransmission(self) -> list[MissionMessage]:
        # The vehicle waits for the last item asked for (it was lost) or, its request for
        # the next lost, for one of those after it: the burst offers them in order, and a
        # vehicle that takes one takes the next from the same burst.
        if not (self.offer_next and self._requested):
            return list(self._last_sent) * self.copies
        first = max(self._requested)
        offers: list[MissionMessage] = [*self.items[first:first + self.copies]]
        self._sent.update(range(first, first + len(offers)))
        return offers


class Download(Transfer):
    """Read the vehicle's items of one mission type; the result is ``items``."""

    operation = "download"

    def __init__(self, mission_type: int = MissionType.MISSION,
                 **options: Unpack[TransferOptions]) -> None:
        super().__init__(mission_type, **options)
        self.count: int | None = None
        self._received: dict[int, MissionItem] = {}

    @property
    def items(self) -> list[MissionItem]:
        """The items received so far, in seq order (all of them once ``succeeded``)."""
        return [self._received[seq] for seq in sorted(self._received)]

    @property
    def progress(self) -> Progress:
        """Items received of the count the vehicle announced."""
        return Progress(len(self._received), self.count or 0)

    def _opening(self) -> MissionMessage:
        return MissionRequestList(self.mission_type)

    def _current_timeout(self) -> float:
        return self.timeout if self.count is None else self.item_timeout

    def _next_missing(self) -> int | None:
        assert self.count is not None
        return next((seq for seq in range(self.count) if seq not in self._received), None)

    def _at(self) -> int | None:
        return None if self.count is None else self._next_missing()

    def _unanswered(self) -> str:
        retried = f"{self.retries} retries {_ms(self._current_timeout())} apart"
        seq = self._at()
        if seq is None:
            return f"no MISSION_COUNT after MISSION_REQUEST_LIST, {retried}"
        return f"no item {seq} (of {self.count}) after MISSION_REQUEST_INT, {retried}"

    def _request_next_or_finish(self, now: float, moved: bool) -> list[MissionMessage]:
        missing = self._next_missing()
        if missing is None:
            self._succeed()
            return [MissionAck(MissionResult.MAV_MISSION_ACCEPTED, self.mission_type)]
        request = MissionRequest(missing, self.mission_type)
        if moved:
            return self._send(now, request)
        # A duplicate (a burst's extra answer): ask again at once, the timer running on.
        return [request]

    def _handle(self, msg: MissionMessage, now: float) -> list[MissionMessage]:
        if isinstance(msg, MissionCount):
            moved = self.count is None
            if moved:
                self.count = msg.count
            return self._request_next_or_finish(now, moved)
        if isinstance(msg, MissionItem) and self.count is not None:
            moved = 0 <= msg.seq < self.count and msg.seq not in self._received
            if moved:
                self._received[msg.seq] = msg
            return self._request_next_or_finish(now, moved)
        if isinstance(msg, MissionAck) and msg.result not in _NO_ANSWER_TO_A_DOWNLOAD:
            self._ack_failure(msg)
        return []


_NO_ANSWER_TO_A_DOWNLOAD = (MissionResult.MAV_MISSION_ACCEPTED, MissionResult.MAV_MISSION_ERROR)
"""Acks a download goes on through. A vehicle serving a download acknowledges nothing of
its own; an ERROR then answers a late copy of the last upload's item (ArduPilot answers an
item it does not expect with MAV_MISSION_ERROR): the read-back of an upload through a slow
link failed on it. Should the vehicle really stop answering, the download times out."""


class Clear(Transfer):
    """Delete the vehicle's items of one mission type (MISSION_CLEAR_ALL)."""

    operation = "clear"

    def _opening(self) -> MissionMessage:
        return MissionClearAll(self.mission_type)

    def _handle(self, msg: MissionMessage, now: float) -> list[MissionMessage]:
        if isinstance(msg, MissionAck):
            if msg.result == MissionResult.MAV_MISSION_ACCEPTED:
                self._succeed()
            else:
                self._ack_failure(msg)
        return []


def _name(msgs: list[MissionMessage]) -> str:
    """The MAVLink name of what was sent last, e.g. ``MISSION_CLEAR_ALL``."""
    names = {MissionItem: "MISSION_ITEM_INT", MissionCount: "MISSION_COUNT",
             MissionRequest: "MISSION_REQUEST_INT", MissionRequestList: "MISSION_REQUEST_LIST",
             MissionClearAll: "MISSION_CLEAR_ALL", MissionAck: "MISSION_ACK"}
    return " and ".join(names[type(msg)] for msg in msgs) or "nothing"


def _ms(seconds: float) -> str:
    return f"{seconds * 1000:.0f} ms"


def with_home_placeholder(items: list[MissionItem], home: MissionItem | None = None
                          ) -> list[MissionItem]:
    """Renumber ``items`` to seq 1..N behind an item 0 for ArduPilot to overwrite with home.

    ``home`` defaults to a NAV_WAYPOINT at 0, 0 in the global frame; ArduPilot ignores its
    contents and keeps its own home there.
    """
    placeholder = home or MissionItem(seq=0, frame=0, command=16)  # MAV_CMD_NAV_WAYPOINT
    return [_renumbered(item, index) for index, item in enumerate([placeholder, *items])]


def _renumbered(item: MissionItem, seq: int) -> MissionItem:
    """``item`` as item ``seq`` (dataclasses.replace costs ten times as much, per item of
    a mission uploaded while the clock runs)."""
    if item.seq == seq:
        return item
    return MissionItem(seq, item.frame, item.command, item.current, item.autocontinue,
                       item.param1, item.param2, item.param3, item.param4, item.x, item.y,
                       item.z, item.mission_type)


# --- read-back: what a vehicle keeps of an item ------------------------------------------
#
# A vehicle reads its mission back in its own storage form, not as it was sent. A *form*
# says, field by field, what an item should read back as: a value, None for a field the
# vehicle does not keep (not compared), or Unstorable for a value the field cannot hold.
# exact_form is a vehicle that stores items as sent; ardupilot_form is
# ArduPilot, after AP_Mission's mavlink_int_to_mission_cmd / mission_cmd_to_mavlink_int
# (missions), AC_PolyFence_loader (fences) and AP_Rally (rally points), checked against
# ArduCopter 4.7 SITL (docs/run.md, "Upload and read-back", lists the rules).


@dataclass(frozen=True)
class Unstorable:
    """A value the vehicle's field cannot hold: it would wrap, or be refused."""

    why: str


Expected = float | int | Unstorable | None
"""What one field should read back as; None for a field the vehicle does not keep."""

ItemForm = Callable[[MissionItem], dict[str, Expected]]
"""The expected read-back of an item, field by field (fields left out are not compared)."""

PARAMS = ("param1", "param2", "param3", "param4")


@dataclass(frozen=True)
class ItemDifference:
    """A field of a sent item that the vehicle read back otherwise.

    ``seq`` and ``command`` are the sent item's; for ``field`` ``"count"`` (the read-back
    holds another number of items) both are None and ``sent``/``read`` are the counts.
    ``expected`` is what the vehicle should have kept of ``sent`` (None when it cannot keep
    it: ``why`` says why).
    """

    seq: int | None
    command: int | None
    field: str
    sent: float | int
    read: float | int
    expected: float | int | None = None
    why: str = ""

    def describe(self, command_name: Callable[[int], str] = lambda c: f"command {c}") -> str:
        """E.g. ``item 3 NAV_WAYPOINT: param1 sent 2.5, read back 3 (expected 2)``."""
        if self.field == "count":
            return f"{_shown(self.read)} items read back, {_shown(self.sent)} sent"
        assert self.command is not None
        text = (f"item {self.seq} {command_name(self.command)}: {self.field} sent "
                f"{_shown(self.sent)}, read back {_shown(self.read)}")
        if self.why:
            return f"{text} ({self.why})"
        if self.expected is not None and not _same(self.field, self.expected, self.sent):
            return f"{text} (expected {_shown(self.expected)})"
        return text


def read_back_differences(sent: list[MissionItem], read_back: list[MissionItem],
                          form: ItemForm | None = None, *, skip_home: bool = False
                          ) -> list[ItemDifference]:
    """Every field of ``sent`` that ``read_back`` does not hold as ``form`` predicts.

    ``form`` defaults to :func:`exact_form`. With ``skip_home`` item 0 is not compared
    (ArduPilot keeps its home there). ``current`` is never compared: vehicles report their
    own current item. Frames are compared by family: an _INT frame and its float twin say
    the same thing (MISSION_ITEM_INT carries integer coordinates in either).
    """
    form = form or exact_form
    found: list[ItemDifference] = []
    if len(sent) != len(read_back):
        found.append(ItemDifference(None, None, "count", len(sent), len(read_back)))
    start = 1 if skip_home else 0
    for item, back in zip(sent[start:], read_back[start:], strict=False):
        found += _item_differences(item, back, form)
    return found


def _item_differences(item: MissionItem, back: MissionItem, form: ItemForm
                      ) -> list[ItemDifference]:
    def difference(name: str, expected: Expected = None) -> ItemDifference:
        if isinstance(expected, Unstorable):
            return ItemDifference(item.seq, item.command, name, getattr(item, name),
                                  getattr(back, name), why=expected.why)
        return ItemDifference(item.seq, item.command, name, getattr(item, name),
                              getattr(back, name), expected)

    found = [difference(name) for name in ("seq", "mission_type")
             if getattr(back, name) != getattr(item, name)]
    if back.command != item.command:
        return [*found, difference("command")]  # the rest of the item means something else
    for name, expected in form(item).items():
        if isinstance(expected, Unstorable) or (
                expected is not None and not _same(name, expected, getattr(back, name))):
            found.append(difference(name, expected))
    return found


def same_items(sent: list[MissionItem], read_back: list[MissionItem], *,
               skip_home: bool = False) -> bool:
    """True if ``read_back`` holds ``sent`` exactly (:func:`exact_form`)."""
    return not read_back_differences(sent, read_back, skip_home=skip_home)


def exact_form(item: MissionItem) -> dict[str, Expected]:
    """Every field as sent, floats as the wire's float32 carries them: a vehicle that stores
    items verbatim (what tml expects of autopilots other than ArduPilot)."""
    return {"frame": item.frame, "autocontinue": item.autocontinue,
            **{name: _f32(getattr(item, name)) for name in PARAMS},
            "x": item.x, "y": item.y, "z": _f32(item.z)}


def ardupilot_form(item: MissionItem) -> dict[str, Expected]:
    """What ArduPilot (Copter) reads back of ``item``: only what it keeps.

    Missions: each command keeps some params, in C types (whole numbers are truncated
    toward zero, and a value outside the type is :class:`Unstorable`), drops the others
    (read back 0, not compared) and never keeps ``autocontinue``. A command with a position
    keeps x and y, the altitude in whole centimetres and the frame's family (GLOBAL,
    RELATIVE_ALT or TERRAIN_ALT; MAV_FRAME_MISSION counts as GLOBAL); a command without one
    keeps neither position nor frame (it reads back frame 0). A command without a rule
    here is compared by command only. Fences keep x, y and param1 (vertex count or
    radius); rally points x, y, the frame's family and the altitude in whole metres.
    """
    if item.mission_type == MissionType.FENCE:
        return _fence_form(item)
    if item.mission_type == MissionType.RALLY:
        return {"frame": _position_frame(item.frame), "x": item.x, "y": item.y,
                "z": _whole(-32768, 32767, "metres")(item.z)}
    rule = _ARDUPILOT_COMMANDS.get(item.command)
    if rule is None:
        return {}
    form: dict[str, Expected] = {name: store(getattr(item, name))
                                 for name, store in zip(PARAMS, rule.params, strict=True)}
    if rule.position:
        form |= {"frame": _position_frame(item.frame), "x": item.x, "y": item.y,
                 "z": _centimetres(item.z)}
    else:
        form |= {"x": rule.x(item.x), "y": rule.y(item.y)}
    return form


def _f32(value: float) -> float:
    rounded: float = struct.unpack("<f", struct.pack("<f", value))[0]
    return rounded


_FRAME_FAMILY = {5: 0, 6: 3, 11: 10}  # an _INT frame -> its float twin


def _same(name: str, expected: float | int, read: float | int) -> bool:
    if name == "frame":
        return _FRAME_FAMILY.get(int(read), read) == _FRAME_FAMILY.get(int(expected), expected)
    if isinstance(expected, float) and math.isnan(expected):
        return isinstance(read, float) and math.isnan(read)
    return _f32(float(read)) == expected if isinstance(read, float) else read == expected


def _shown(value: float | int) -> str:
    """A number as the wire carries it, as short as it reads: 2.0 -> 2, 12.3 -> 12.3."""
    if isinstance(value, int) or not math.isfinite(value):
        return str(value)
    value = _f32(value)
    if value.is_integer():
        return str(int(value))
    for digits in range(1, 10):
        text = f"{value:.{digits}g}"
        if _f32(float(text)) == value:
            return text
    return repr(value)


# ArduPilot's storage of one field, from the value sent (float32 on the wire).
Store = Callable[[float], Expected]


def _not_kept(value: float) -> Expected:
    return None


def _kept(value: float) -> Expected:
    return _f32(value)


def _whole(low: int, high: int, unit: str = "") -> Store:
    """A C integer field from low to high: the fraction dropped toward zero."""
    what = f"whole {unit}" if unit else "whole numbers"

    def store(value: float) -> Expected:
        v = _f32(value)
        if math.isnan(v) or not low - 1 < v < high + 1:
            return Unstorable(f"ArduPilot keeps {what} from {low} to {high} here")
        return float(math.trunc(v))
    return store


_U8, _I8, _U16, _I16 = _whole(0, 255), _whole(-128, 127), _whole(0, 65535), _whole(-32768, 32767)


def _direction(value: float) -> Expected:
    """Only the sign kept, as -1 or 1 (NAV_LOITER_TIME's radius)."""
    return -1.0 if _f32(value) < 0 else 1.0


def _land_direction(value: float) -> Expected:
    """NAV_LAND param4 (a yaw): kept as its sign, -1 only below -FLT_EPSILON; NaN reads 1."""
    v = _f32(value)
    return -1.0 if not math.isnan(v) and v <= -1.1920929e-07 else 1.0


def _flag(value: float) -> Expected:
    """1 when positive, else 0 (a loiter's exit on the tangent)."""
    return 1.0 if _f32(value) > 0 else 0.0


def _signed_whole(value: float) -> Expected:
    """A radius kept as whole metres (0 to 65535) with its sign (the loiter direction)."""
    v = _f32(value)
    metres = _U16(abs(v))
    if not isinstance(metres, float):
        return metres
    return -metres if v < 0 else metres


def _turns(value: float) -> Expected:
    """NAV_LOITER_TURNS param1: whole turns up to 255; below 1, in 256ths of a turn."""
    v = _f32(value)
    if 0 < v < 1:
        return math.trunc(v * 256) / 256
    if math.isnan(v) or v <= -1:
        return Unstorable(f"ArduPilot keeps 0 to {LOITER_TURNS_MAX} turns")
    return float(min(LOITER_TURNS_MAX, math.trunc(v)))


def _loiter_radius(value: float) -> Expected:
    """NAV_LOITER_TURNS param3: whole metres to 255 m, then tens of metres up to 2550 m,
    signed by the direction."""
    v = _f32(value)
    if math.isnan(v):
        return Unstorable("ArduPilot keeps no NaN radius")
    radius = abs(v)
    metres = math.trunc(radius) if radius <= 255 else min(255, math.trunc(radius * 0.1)) * 10
    return -float(metres) if v < 0 else float(metres)


def _centimetres(value: float) -> Expected:
    """A position's altitude: whole centimetres (float32 arithmetic), below 83 km."""
    v = _f32(value)
    if math.isnan(v) or abs(v) >= 83000:
        return Unstorable("ArduPilot keeps altitudes below 83 km")
    return _f32(_f32(float(math.trunc(_f32(v * 100.0)))) * _f32(0.01))


def _position_frame(frame: int) -> Expected:
    family = {0: 0, 2: 0, 5: 0, 3: 3, 6: 3, 10: 10, 11: 10}.get(frame)
    if family is None:
        return Unstorable(f"ArduPilot takes no position in frame {frame}")
    return family


@dataclass(frozen=True)
class _Rule:
    """How ArduPilot stores one command: with a position or not, and each param."""

    position: bool
    params: tuple[Store, Store, Store, Store]
    x: Store = _not_kept
    y: Store = _not_kept


_ = _not_kept
_ARDUPILOT_COMMANDS: dict[int, _Rule] = {
    16: _Rule(True, (_U16, _, _, _)),  # NAV_WAYPOINT: hold s (Copter; yaw not kept)
    17: _Rule(True, (_, _, _signed_whole, _)),  # NAV_LOITER_UNLIM: radius
    18: _Rule(True, (_turns, _, _loiter_radius, _flag)),  # NAV_LOITER_TURNS
    19: _Rule(True, (_U16, _, _direction, _flag)),  # NAV_LOITER_TIME: s; radius's sign only
    20: _Rule(False, (_, _, _, _)),  # NAV_RETURN_TO_LAUNCH
    21: _Rule(True, (_U16, _, _, _land_direction)),  # NAV_LAND: abort alt; yaw's sign
    22: _Rule(True, (_U16, _, _, _)),  # NAV_TAKEOFF: pitch (Plane)
    31: _Rule(True, (_, _signed_whole, _, _flag)),  # NAV_LOITER_TO_ALT: radius
    82: _Rule(True, (_U16, _, _, _)),  # NAV_SPLINE_WAYPOINT: hold s
    84: _Rule(True, (_, _, _, _)),  # NAV_VTOL_TAKEOFF
    85: _Rule(True, (_U16, _, _, _)),  # NAV_VTOL_LAND: options
    92: _Rule(True, (_U16, _, _, _)),  # NAV_GUIDED_ENABLE
    93: _Rule(False, (_kept, _I8, _I8, _I8)),  # NAV_DELAY: s; UTC hour, min, s
    112: _Rule(False, (_kept, _, _, _)),  # CONDITION_DELAY
    114: _Rule(False, (_kept, _, _, _)),  # CONDITION_DISTANCE
    115: _Rule(False, (_kept, _kept, _I8, _U8)),  # CONDITION_YAW: deg, deg/s, dir, relative
    177: _Rule(False, (_U16, _I16, _, _)),  # DO_JUMP: target, repeat
    178: _Rule(False, (_U8, _kept, _kept, _)),  # DO_CHANGE_SPEED: type, m/s, throttle
    179: _Rule(True, (_U16, _, _, _)),  # DO_SET_HOME: use current
    181: _Rule(False, (_U8, _U8, _, _)),  # DO_SET_RELAY
    183: _Rule(False, (_U8, _U16, _, _)),  # DO_SET_SERVO
    195: _Rule(True, (_U16, _, _, _)),  # DO_SET_ROI_LOCATION
    197: _Rule(False, (_U16, _, _, _)),  # DO_SET_ROI_NONE
    201: _Rule(True, (_U16, _, _, _)),  # DO_SET_ROI
    203: _Rule(False, (_U8, _U8, _I8, _U8), _U8, _U8),  # DO_DIGICAM_CONTROL (+ shoot, id)
    205: _Rule(False, (_kept, _kept, _kept, _)),  # DO_MOUNT_CONTROL: pitch, roll, yaw
    206: _Rule(False, (_kept, _, _U8, _)),  # DO_SET_CAM_TRIGG_DIST: m, trigger now
    211: _Rule(False, (_U8, _U8, _, _)),  # DO_GRIPPER: instance, action
    2000: _Rule(False, (_U8, _kept, _U16, _U16)),  # IMAGE_START_CAPTURE
    2001: _Rule(False, (_U16, _, _, _)),  # IMAGE_STOP_CAPTURE
}
del _


def _fence_form(item: MissionItem) -> dict[str, Expected]:
    # Fences have no altitude (frame and z read back 0); param1 is a polygon's vertex
    # count (uint8) or a circle's radius (float).
    param1 = _U8 if item.command in (5001, 5002) else _kept if item.command in (
        5003, 5004) else _not_kept
    return {"param1": param1(item.param1), "x": item.x, "y": item.y}
