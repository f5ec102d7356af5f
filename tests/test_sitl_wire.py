"""sitl.wire: the simulator's packets are byte for byte the ones pymavlink packs, from a
message or from the arguments that would build it."""

from __future__ import annotations

import random
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl.model import VehicleModel
from sitl.wire import Fields, encode
from tml.world import Home

RANGES = {
    "int8_t": (-128, 127), "uint8_t": (0, 255), "int16_t": (-32768, 32767),
    "uint16_t": (0, 65535), "int32_t": (-(2**31), 2**31 - 1), "uint32_t": (0, 2**32 - 1),
    "int64_t": (-(2**63), 2**63 - 1), "uint64_t": (0, 2**64 - 1),
}


def _value(kind: str, rnd: random.Random, zero: bool) -> Any:
    if kind in ("float", "double"):
        return 0.0 if zero else rnd.uniform(-1e6, 1e6)
    low, high = RANGES[kind]
    return 0 if zero else rnd.randint(low, high)


def _arguments(kind: type, rnd: random.Random, zero: bool) -> list[Any]:
    args: list[Any] = []
    for index, name in enumerate(kind.fieldnames):
        field_type = kind.fieldtypes[index]
        length = kind.array_lengths[kind.ordered_fieldnames.index(name)]
        if field_type == "char":
            size = length or 1
            args.append(b"" if zero else bytes(rnd.randint(65, 90)
                                                for _ in range(rnd.randint(1, size))))
        elif length:
            # A tail of zeros sometimes, so the cut of trailing zero bytes is exercised.
            args.append([0 if zero or rnd.random() < 0.3 else _value(field_type, rnd, False)
                         for _ in range(length)])
        else:
            args.append(_value(field_type, rnd, zero or rnd.random() < 0.3))
    return args


def _message(kind: type, rnd: random.Random, zero: bool) -> Any:
    return kind(*_arguments(kind, rnd, zero))


@pytest.mark.parametrize("msg_id", sorted(mavlink.mavlink_map))
def test_every_message_encodes_as_pymavlink_packs_it(msg_id: int) -> None:
    kind = mavlink.mavlink_map[msg_id]
    rnd = random.Random(msg_id)
    for round_ in range(6):
        msg = _message(kind, rnd, zero=round_ == 0)
        seq, system, component = rnd.randint(0, 255), rnd.randint(1, 255), rnd.randint(0, 255)
        link = mavlink.MAVLink(None, system, component)
        link.seq = seq
        assert encode(msg, seq, system, component) == msg.pack(link)


@pytest.mark.parametrize("msg_id", sorted(mavlink.mavlink_map))
def test_every_message_encodes_from_its_arguments_as_pymavlink_packs_it(msg_id: int) -> None:
    kind = mavlink.mavlink_map[msg_id]
    rnd = random.Random(-msg_id)
    required = kind.__init__.__code__.co_argcount - 1 - len(kind.__init__.__defaults__ or ())
    for round_ in range(6):
        args = _arguments(kind, rnd, zero=round_ == 0)
        # Some rounds leave out the extensions, all or the later half of them, as a
        # builder may: the defaults fill them.
        given = tuple(args[:(len(args), required, (required + len(args) + 1) // 2)[round_ % 3]])
        seq, system, component = rnd.randint(0, 255), rnd.randint(1, 255), rnd.randint(0, 255)
        link = mavlink.MAVLink(None, system, component)
        link.seq = seq
        assert encode(Fields(kind, given), seq, system, component) == kind(*given).pack(link)


def test_a_packet_decodes_to_the_message_and_its_sender() -> None:
    msg = mavlink.MAVLink_statustext_message(6, b"Takeoff")
    decoded = mavlink.MAVLink(None).decode(bytearray(encode(msg, 7, 3, 1)))
    assert decoded.get_type() == "STATUSTEXT" and decoded.text == "Takeoff"
    assert (decoded.get_seq(), decoded.get_srcSystem(), decoded.get_srcComponent()) == (7, 3, 1)


def test_a_flight_streams_the_same_bytes_unbuilt_as_built() -> None:
    """Two twins fly the same take-off with every stream at 4 Hz: the telemetry encoded
    from its arguments (as the server sends it) is the telemetry encoded from the built
    messages, packet for packet."""
    home = Home(-35.363261, 149.165230, 584.0)
    twins = [VehicleModel(1, home, params={"SIM_GPS_LOCKTIME": 1, "SIM_EKF_GPS_TIME": 2})
             for _ in range(2)]
    for model in twins:
        model.handle(mavlink.MAVLink_request_data_stream_message(
            1, 1, mavlink.MAV_DATA_STREAM_ALL, 4, 1))
        for msg_id in (mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
                       mavlink.MAVLINK_MSG_ID_HOME_POSITION,
                       mavlink.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN):
            model.handle(mavlink.MAVLink_command_long_message(
                1, 1, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0, msg_id, 250_000, 0, 0, 0, 0, 0))
    unbuilt, built = twins
    packets = 0
    kinds = set()
    for second in range(30):
        if second == 5:
            for model in twins:
                model.set_mode("GUIDED")
                model.handle(mavlink.MAVLink_command_long_message(1, 1, 400, 0, 1, 0, 0, 0, 0,
                                                                  0, 0))
                model.handle(mavlink.MAVLink_command_long_message(1, 1, 22, 0, 0, 0, 0, 0, 0,
                                                                  0, 20))
        items = unbuilt.step_wire(1.0)
        kinds |= {type(item) for item in items}
        sent = [encode(item, 0, 1, 1) for item in items]
        assert sent == [encode(msg, 0, 1, 1) for msg in built.step(1.0)]
        packets += len(sent)
    assert Fields in kinds and packets > 30 * 50
