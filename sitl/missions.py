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
- Items are stored as ArduCopter stores them (:mod:`sitl.storage`) and read back in that
  form: frames of positions as GLOBAL / GLOBAL_RELATIVE_ALT / GLOBAL_TERRAIN_ALT, other
  commands' frames as 0, only the params ArduCopter keeps, whole numbers where it keeps
  integers. An item ArduCopter refuses (unknown command, NaN param, a position out of
  range or in a frame it does not take) ends the upload with ArduCopter's MISSION_ACK
  result.
- Seq 0 of a mission is home: whatever the client uploads there is replaced by the
  vehicle's home (read back with frame GLOBAL and absolute altitude).
- Uploads are refused with NO_SPACE for :data:`BOOT_BUSY` seconds after boot, as
  ArduCopter does while its storage initialises, and when the count is too large.
- Download (MISSION_REQUEST_LIST, then MISSION_REQUEST[_INT] per item) and clear
  (MISSION_CLEAR_ALL) are answered at once.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl import storage
from sitl.items import MissionItem
from sitl.results import MissionResult

REQUEST_INTERVAL = 1.0  # seconds after a request before the item is requested again
UPLOAD_TIMEOUT = 8.0  # seconds without an item before the upload is cancelled
BOOT_BUSY = 1.0  # seconds after boot during which uploads get NO_SPACE
MAX_ITEMS = {0: 725, 1: 84, 2: 20}  # capacity per MAV_MISSION_TYPE (ArduCopter SITL's)

MISSION, FENCE, RALLY = storage.MISSION, storage.FENCE, storage.RALLY


def item_from_message(msg: Any) -> MissionItem | MissionResult:
    """The item a MISSION_ITEM (degrees) or MISSION_ITEM_INT (degrees * 1e7) asks to store,
    in the form the vehicle stores it, or the MAV_MISSION_RESULT refusing it."""
    mission_type = getattr(msg, "mission_type", MISSION)
    x, y = msg.x, msg.y
    if msg.get_type() == "MISSION_ITEM":
        coordinates = storage.int_coordinates(msg.command, msg.x, msg.y)
        if isinstance(coordinates, int):
            return coordinates
        x, y = coordinates
    stored = storage.store(mission_type, msg.command, msg.frame,
                           (msg.param1, msg.param2, msg.param3, msg.param4), x, y, msg.z)
    if isinstance(stored, int):
        return stored
    return MissionItem(
        seq=msg.seq, frame=stored.frame, command=msg.command, current=0,
        autocontinue=stored.autocontinue, param1=stored.params[0], param2=stored.params[1],
        param3=stored.params[2], param4=stored.params[3], x=stored.x, y=stored.y, z=stored.z,
        mission_type=mission_type,
    )


def item_to_message(item: MissionItem, target: tuple[int, int], as_int: bool) -> Any:
    """``item`` as MISSION_ITEM_INT (``as_int``) or MISSION_ITEM addressed to ``target``."""
    values = (item.seq, item.frame, item.command, item.current, item.autocontinue,
              item.param1, item.param2, item.param3, item.param4)
    if as_int:
        return mavlink.MAVLink_mission_item_int_message(
            *target, *values, item.x, item.y, item.z, item.mission_type)
    # ArduPilot scales a position's integers back to degrees in float32 arithmetic.
    if item.command in storage.POSITION or item.mission_type in (FENCE, RALLY):
        x, y = (storage.f32(storage.f32(v) * storage.f32(1e-7)) for v in (item.x, item.y))
    else:
        x, y = float(item.x), float(item.y)
    return mavlink.MAVLink_mission_item_message(
        *target, *values, x, y, item.z, item.mission_type)


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


def _ack(target: tuple[int, int], result: MissionResult, mission_type: int) -> Any:
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

    def count(self, mission_type: int = MISSION) -> int:
        """How many items :meth:`items` holds, without copying them."""
        return len(self._lists[mission_type])

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
            return [_ack(_sender(msg), MissionResult.DENIED, mission_type)]
        if kind == "MISSION_REQUEST_LIST":
            if mission_type not in self._lists:
                return [_ack(_sender(msg), MissionResult.UNSUPPORTED, mission_type)]
            count = len(self.items(mission_type))
            return [mavlink.MAVLink_mission_count_message(*_sender(msg), count, mission_type)]
        if kind in ("MISSION_REQUEST", "MISSION_REQUEST_INT"):
            as_int = kind == "MISSION_REQUEST_INT"
            self._client_uses_int = self._client_uses_int or as_int
            items = self.items(mission_type) if mission_type in self._lists else []
            if not 0 <= msg.seq < len(items):
                return [_ack(_sender(msg), MissionResult.INVALID_SEQUENCE, mission_type)]
            return [item_to_message(items[msg.seq], _sender(msg), as_int)]
        if kind == "MISSION_CLEAR_ALL":
            types = list(self._lists) if mission_type == mavlink.MAV_MISSION_TYPE_ALL else [
                mission_type
            ]
            if any(t not in self._lists for t in types):
                return [_ack(_sender(msg), MissionResult.UNSUPPORTED, mission_type)]
            if any(self._uploading(t) for t in types):
                return [_ack(_sender(msg), MissionResult.ERROR, mission_type)]
            for t in types:
                self._lists[t] = []
                self._on_change(t)
            return [_ack(_sender(msg), MissionResult.ACCEPTED, mission_type)]
        return []

    def tick(self, now: float) -> list[Any]:
        """Cancel an upload silent for too long, or request the awaited item again."""
        upload = self._upload
        if upload is None:
            return []
        if now - upload.received_at > UPLOAD_TIMEOUT:
            self._upload = None
            return [_ack(upload.client, MissionResult.OPERATION_CANCELLED,
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
            return [_ack(client, MissionResult.UNSUPPORTED, mission_type)]
        busy = self._upload
        if busy is not None and busy.mission_type == mission_type and busy.client != client:
            return [_ack(client, MissionResult.DENIED, mission_type)]
        if now < BOOT_BUSY or msg.count > MAX_ITEMS[mission_type]:
            return [_ack(client, MissionResult.NO_SPACE, mission_type)]
        if msg.count == 0:
            self._upload = None
            self._lists[mission_type] = []
            self._on_change(mission_type)
            return [_ack(client, MissionResult.ACCEPTED, mission_type)]
        self._upload = _Upload(mission_type, msg.count, client, [], now, now)
        return [self._request(self._upload, now)]

    def _receive_item(self, msg: Any, now: float) -> list[Any]:
        client = _sender(msg)
        mission_type = getattr(msg, "mission_type", MISSION)
        upload = self._upload
        if upload is None or upload.mission_type != mission_type:
            # No upload of this list (it ended, or timed out): ArduPilot answers an item it
            # does not expect with MAV_MISSION_ERROR, never with a late ACCEPTED.
            return [_ack(client, MissionResult.ERROR, mission_type)]
        if msg.seq != len(upload.items):
            return [_ack(client, MissionResult.INVALID_SEQUENCE, mission_type)]
        if client != upload.client:
            return [_ack(client, MissionResult.DENIED, mission_type)]
        item = item_from_message(msg)
        if isinstance(item, int):  # refused, as ArduPilot ends an upload on a bad item
            self._upload = None
            return [_ack(client, item, mission_type)]
        upload.items.append(item)
        upload.received_at = now
        if len(upload.items) < upload.count:
            return [self._request(upload, now)]
        self._upload = None
        self._lists[mission_type] = upload.items
        self._on_change(mission_type)
        return [_ack(client, MissionResult.ACCEPTED, mission_type)]
