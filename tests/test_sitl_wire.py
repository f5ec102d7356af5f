"""sitl.wire: the simulator's packets are byte for byte the ones pymavlink packs."""

from __future__ import annotations

import random
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl.wire import encode

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


def _message(kind: type, rnd: random.Random, zero: bool) -> Any:
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
    return kind(*args)


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


def test_a_packet_decodes_to_the_message_and_its_sender() -> None:
    msg = mavlink.MAVLink_statustext_message(6, b"Takeoff")
    decoded = mavlink.MAVLink(None).decode(bytearray(encode(msg, 7, 3, 1)))
    assert decoded.get_type() == "STATUSTEXT" and decoded.text == "Takeoff"
    assert (decoded.get_seq(), decoded.get_srcSystem(), decoded.get_srcComponent()) == (7, 3, 1)
