"""Plain messages survive the trip through pymavlink's MAVLink 2 encoder and parser."""

from __future__ import annotations

import pytest

from tml.mavlink.codec import (
    command_name,
    command_text,
    decode,
    encode,
    enum_name,
    gcs_heartbeat,
    mavlink,
)
from tml.mavlink.command import CommandAck, CommandInt, CommandLong, Heartbeat
from tml.mavlink.mission import (
    MissionAck,
    MissionClearAll,
    MissionCount,
    MissionItem,
    MissionRequest,
    MissionRequestList,
)


def over_the_wire(msg: mavlink.MAVLink_message, seq: int = 0) -> mavlink.MAVLink_message:
    sender = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    sender.seq = seq
    data = msg.pack(sender)
    assert data[0] == mavlink.PROTOCOL_MARKER_V2
    parsed = mavlink.MAVLink(None).parse_buffer(data)
    assert parsed is not None and len(parsed) == 1
    return parsed[0]


ROUND_TRIPS = [
    MissionItem(seq=3, frame=6, command=16, current=0, autocontinue=1, param1=2.5, param4=90.0,
                x=-353632621, y=1491652374, z=25.0, mission_type=0),
    MissionItem(seq=1, frame=6, command=5001, param1=4.0, x=-353600000, y=1491600000,
                mission_type=1),
    MissionCount(101, 2),
    MissionRequest(7, 0, legacy=True),
    MissionRequest(7, 1),
    MissionRequestList(1),
    MissionClearAll(2),
    MissionAck(13, 0),
    CommandAck(22, 5, progress=50),
]


@pytest.mark.parametrize("plain", ROUND_TRIPS, ids=lambda m: type(m).__name__)
def test_plain_messages_round_trip(plain: object) -> None:
    wire = over_the_wire(encode(plain, 1, 1))  # type: ignore[arg-type]
    assert (wire.target_system, wire.target_component) == (1, 1) or plain.__class__ is CommandAck
    assert decode(wire) == plain


def test_legacy_request_is_mission_request_id_40_and_items_go_as_mission_item_int() -> None:
    assert encode(MissionRequest(0, legacy=True), 1, 1).get_msgId() == 40
    assert encode(MissionRequest(0), 1, 1).get_msgId() == 51
    assert encode(ROUND_TRIPS[0], 1, 1).get_type() == "MISSION_ITEM_INT"


def test_legacy_float_mission_item_is_read_as_degrees_times_1e7() -> None:
    legacy = mavlink.MAVLink(None).mission_item_encode(
        255, 190, 2, 3, 16, 0, 1, 0, 0, 0, 0, -35.3632621, 149.1652374, 30.0, 0)
    item = decode(over_the_wire(legacy))
    assert isinstance(item, MissionItem)
    assert abs(item.x - -353632621) <= 2 and abs(item.y - 1491652374) <= 8


def test_commands_are_encoded_with_all_their_fields() -> None:
    long = over_the_wire(encode(CommandLong(400, 1.0, 21196.0, confirmation=2), 3, 1))
    assert (long.command, long.param1, long.param2, long.confirmation) == (400, 1.0, 21196.0, 2)
    goto = over_the_wire(encode(CommandInt(192, frame=6, param1=-1, x=10, y=20, z=30.0), 3, 1))
    assert (goto.command, goto.frame, goto.x, goto.y, goto.z) == (192, 6, 10, 20, 30.0)


def test_heartbeats_and_acks_carry_their_packet_sequence_number() -> None:
    beat = mavlink.MAVLink(None).heartbeat_encode(
        mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
        mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4, mavlink.MAV_STATE_ACTIVE)
    plain = decode(over_the_wire(beat, seq=200))
    assert plain == Heartbeat(2, 3, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4)
    assert isinstance(plain, Heartbeat) and plain.packet_seq == 200
    ack = decode(over_the_wire(encode(CommandAck(176, 0), 255, 190), seq=201))
    assert isinstance(ack, CommandAck) and ack.packet_seq == 201


def test_other_messages_are_not_decoded() -> None:
    assert decode(mavlink.MAVLink(None).attitude_encode(0, 0, 0, 0, 0, 0, 0)) is None


def test_names_of_commands_and_enums() -> None:
    assert command_name(22) == "MAV_CMD_NAV_TAKEOFF"
    assert command_name(65000) == "MAV_CMD_65000"
    assert command_text(114) == "MAV_CMD_CONDITION_DISTANCE (114)"
    assert command_text(116) == "MAV_CMD 116 (unknown)"
    assert enum_name("MAV_STATE", 4) == "MAV_STATE_ACTIVE"
    assert gcs_heartbeat().type == mavlink.MAV_TYPE_GCS
