"""The vehicle side of the MAVLink mission protocol, for missions, fences and rally points.

Sans-IO: :meth:`MissionServer.handle` takes a decoded message and the vehicle time and
returns the replies; :meth:`MissionServer.tick` returns the re-requests and give-ups that
the time alone causes. Behaviour copied from ArduCopter:

- Upload: MISSION_COUNT -> the vehicle requests each item in turn, with the legacy
  MISSION_REQUEST (id 40) unless the client showed it speaks the _INT protocol by sending
  MISSION_REQUEST_INT itself; MISSION_ITEM and MISSION_ITEM_INT replies are both accepted.
  The vehicle side's timeouts are ArduPilot's (MissionItemProtocol::update): the item
  waited for is requested again whenever :data:`REQUEST_INTERVAL` seconds pass after the
  last request, and the upload is cancelled (MISSION_ACK OPERATION_CANCELLED) once no
  item has arrived for :data:`UPLOAD_TIMEOUT` seconds. These run on :meth:`tick`, which the
  vehicle calls every control step with its own time.
- Any item other than the one waited for (a repeat of one already stored, or one from the
  future) is answered MISSION_ACK INVALID_SEQUENCE and changes nothing; an item from
  another client than the one uploading gets DENIED. Once the upload has ended, items get
  no answer at all: ArduPilot never repeats a final ACK that was lost, so a client settles
  such an upload by reading the mission back.
- While an upload of a list is in progress, another client's MISSION_COUNT for it is
  DENIED (the same client's restarts the upload), downloads of it are DENIED and
  MISSION_CLEAR_ALL of it fails with ERROR.
- Seq 0 of a mission is home: whatever the client uploads there is replaced by the
  vehicle's home (read back with frame GLOBAL and absolute altitude).
- Uploads are refused with NO_SPACE for :data:`BOOT_BUSY` seconds after boot, as
  ArduCopter does while its storage initialises, and when the count is too large.
- Download (MISSION_REQUEST_LIST, then MISSION_REQUEST[_INT] per item) and clear
  (MISSION_CLEAR_ALL) are answered at once.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from tml.mavlink.mission import MissionItem

REQUEST_INTERVAL = 1.0  # seconds after a request before the item is requested again
UPLOAD_TIMEOUT = 8.0  # seconds without an item before the upload is cancelled
BOOT_BUSY = 1.0  # seconds after boot during which uploads get NO_SPACE
MAX_ITEMS = {0: 725, 1: 84, 2: 20}  # capacity per MAV_MISSION_TYPE (ArduCopter SITL's)

MISSION, FENCE, RALLY = 0, 1, 2
GLOBAL_FRAMES = frozenset({0, 3, 5, 6, 10, 11})
ALLOWED_FRAMES = GLOBAL_FRAMES | {2}
FENCE_COMMANDS = frozenset({5000, 5001, 5002, 5003, 5004})
RALLY_COMMANDS = frozenset({5100})


def item_from_message(msg: Any) -> MissionItem:
    """A stored item from MISSION_ITEM (float degrees) or MISSION_ITEM_INT (degrees * 1e7)."""
    if msg.get_type() == "MISSION_ITEM" and msg.frame in GLOBAL_FRAMES:
        x, y = round(msg.x * 1e7), round(msg.y * 1e7)
    else:
        x, y = int(msg.x), int(msg.y)
    return MissionItem(
        seq=msg.seq, frame=msg.frame, command=msg.command, current=msg.current,
        autocontinue=msg.autocontinue, param1=msg.param1, param2=msg.param2,
        param3=msg.param3, param4=msg.param4, x=x, y=y, z=msg.z,
        mission_type=getattr(msg, "mission_type", MISSION),
    )


def item_to_message(item: MissionItem, target: tuple[int, int], as_int: bool) -> Any:
    """``item`` as MISSION_ITEM_INT (``as_int``) or MISSION_ITEM addressed to ``target``."""
    values = (item.seq, item.frame, item.command, item.current, item.autocontinue,
              item.param1, item.param2, item.param3, item.param4)
    if as_int:
        return mavlink.MAVLink_mission_item_int_message(
            *target, *values, item.x, item.y, item.z, item.mission_type)
    scale = 1e-7 if item.frame in GLOBAL_FRAMES else 1.0
    return mavlink.MAVLink_mission_item_message(
        *target, *values, item.x * scale, item.y * scale, item.z, item.mission_type)


@dataclass
class _Upload:
    mission_type: int
    count: int
    client: tuple[int, int]
    items: list[MissionItem]
    requested_at: float  # vehicle time of the last MISSION_REQUEST
    received_at: float  # vehicle time of the start, then of the last item stored


def _sender(msg: Any) -> tuple[int, int]:
    return msg.get_srcSystem(), msg.get_srcComponent()


def _ack(target: tuple[int, int], result: int, mission_type: int) -> Any:
    return mavlink.MAVLink_mission_ack_message(target[0], target[1], result, mission_type)


class MissionServer:
    """Stores the three lists and runs the transfers; ``home_item`` supplies mission seq 0.

    ``on_change(mission_type)`` is called after a list is replaced or cleared.
    """

    def __init__(
        self,
        home_item: Callable[[], MissionItem],
        on_change: Callable[[int], None] = lambda mission_type: None,
    ) -> None:
        self._home_item = home_item
        self._on_change = on_change
        self._lists: dict[int, list[MissionItem]] = {MISSION: [], FENCE: [], RALLY: []}
        self._upload: _Upload | None = None
        self._client_uses_int = False

    def items(self, mission_type: int = MISSION) -> list[MissionItem]:
        """The stored list; for missions item 0 is the current home."""
        stored = self._lists[mission_type]
        if mission_type == MISSION and stored:
            return [self._home_item(), *stored[1:]]
        return list(stored)

    def handle(self, msg: Any, now: float) -> list[Any]:
        """Replies to one mission-protocol message (other messages give an empty list)."""
        kind = msg.get_type()
        if kind == "MISSION_COUNT":
            return self._start_upload(msg, now)
        if kind in ("MISSION_ITEM", "MISSION_ITEM_INT"):
            return self._receive_item(msg, now)
        mission_type = getattr(msg, "mission_type", MISSION)
        if kind in ("MISSION_REQUEST_LIST", "MISSION_REQUEST", "MISSION_REQUEST_INT") and (
                self._uploading(mission_type)):  # no reading a list while it is being written
            return [_ack(_sender(msg), mavlink.MAV_MISSION_DENIED, mission_type)]
        if kind == "MISSION_REQUEST_LIST":
            if mission_type not in self._lists:
                return [_ack(_sender(msg), mavlink.MAV_MISSION_UNSUPPORTED, mission_type)]
            count = len(self.items(mission_type))
            return [mavlink.MAVLink_mission_count_message(*_sender(msg), count, mission_type)]
        if kind in ("MISSION_REQUEST", "MISSION_REQUEST_INT"):
            as_int = kind == "MISSION_REQUEST_INT"
            self._client_uses_int = self._client_uses_int or as_int
            items = self.items(mission_type) if mission_type in self._lists else []
            if not 0 <= msg.seq < len(items):
                return [_ack(_sender(msg), mavlink.MAV_MISSION_INVALID_SEQUENCE, mission_type)]
            return [item_to_message(items[msg.seq], _sender(msg), as_int)]
        if kind == "MISSION_CLEAR_ALL":
            types = list(self._lists) if mission_type == mavlink.MAV_MISSION_TYPE_ALL else [
                mission_type
            ]
            if any(t not in self._lists for t in types):
                return [_ack(_sender(msg), mavlink.MAV_MISSION_UNSUPPORTED, mission_type)]
            if any(self._uploading(t) for t in types):
                return [_ack(_sender(msg), mavlink.MAV_MISSION_ERROR, mission_type)]
            for t in types:
                self._lists[t] = []
                self._on_change(t)
            return [_ack(_sender(msg), mavlink.MAV_MISSION_ACCEPTED, mission_type)]
        return []

    def tick(self, now: float) -> list[Any]:
        """Cancel an upload silent for too long, or request the awaited item again."""
        upload = self._upload
        if upload is None:
            return []
        if now - upload.received_at > UPLOAD_TIMEOUT:
            self._upload = None
            return [_ack(upload.client, mavlink.MAV_MISSION_OPERATION_CANCELLED,
                         upload.mission_type)]
        if now - upload.requested_at > REQUEST_INTERVAL:
            return [self._request(upload, now)]
        return []

    def _uploading(self, mission_type: int) -> bool:
        return self._upload is not None and self._upload.mission_type == mission_type

    def _request(self, upload: _Upload, now: float) -> Any:
        upload.requested_at = now
        seq = len(upload.items)
        if self._client_uses_int:
            return mavlink.MAVLink_mission_request_int_message(
                *upload.client, seq, upload.mission_type
            )
        return mavlink.MAVLink_mission_request_message(*upload.client, seq, upload.mission_type)

    def _start_upload(self, msg: Any, now: float) -> list[Any]:
        client = _sender(msg)
        mission_type = getattr(msg, "mission_type", MISSION)
        if mission_type not in self._lists:
            return [_ack(client, mavlink.MAV_MISSION_UNSUPPORTED, mission_type)]
        busy = self._upload
        if busy is not None and busy.mission_type == mission_type and busy.client != client:
            return [_ack(client, mavlink.MAV_MISSION_DENIED, mission_type)]
        if now < BOOT_BUSY or msg.count > MAX_ITEMS[mission_type]:
            return [_ack(client, mavlink.MAV_MISSION_NO_SPACE, mission_type)]
        if msg.count == 0:
            self._upload = None
            self._lists[mission_type] = []
            self._on_change(mission_type)
            return [_ack(client, mavlink.MAV_MISSION_ACCEPTED, mission_type)]
        self._upload = _Upload(mission_type, msg.count, client, [], now, now)
        return [self._request(self._upload, now)]

    def _receive_item(self, msg: Any, now: float) -> list[Any]:
        client = _sender(msg)
        mission_type = getattr(msg, "mission_type", MISSION)
        upload = self._upload
        if upload is None or upload.mission_type != mission_type:
            return []  # no upload of this list: ArduPilot says nothing, not even a late ACK
        if msg.seq != len(upload.items):
            return [_ack(client, mavlink.MAV_MISSION_INVALID_SEQUENCE, mission_type)]
        if client != upload.client:
            return [_ack(client, mavlink.MAV_MISSION_DENIED, mission_type)]
        item = item_from_message(msg)
        problem = _check(item)
        if problem is not None:
            self._upload = None
            return [_ack(client, problem, mission_type)]
        upload.items.append(replace(item, mission_type=mission_type))
        upload.received_at = now
        if len(upload.items) < upload.count:
            return [self._request(upload, now)]
        self._upload = None
        self._lists[mission_type] = upload.items
        self._on_change(mission_type)
        return [_ack(client, mavlink.MAV_MISSION_ACCEPTED, mission_type)]


def _check(item: MissionItem) -> int | None:
    """The MAV_MISSION_RESULT that refuses ``item``, or None when it is acceptable."""
    if item.mission_type == FENCE and item.command not in FENCE_COMMANDS:
        return mavlink.MAV_MISSION_UNSUPPORTED
    if item.mission_type == RALLY and item.command not in RALLY_COMMANDS:
        return mavlink.MAV_MISSION_UNSUPPORTED
    if item.frame not in ALLOWED_FRAMES:
        return mavlink.MAV_MISSION_UNSUPPORTED_FRAME
    return None
