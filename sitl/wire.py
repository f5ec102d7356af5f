"""MAVLink 2 packets from pymavlink messages, at a quarter of ``msg.pack``'s cost or less.

The simulator encodes every telemetry message of every vehicle, several hundred a
vehicle-second when a client asks for all streams, and pymavlink's ``pack`` spends most
of its time outside the payload: a header object, a CRC object, a bytearray copied to
bytes, a version check, per packet (docs/performance.md). :func:`encode` builds the same
bytes directly: the payload with the message's own ``struct`` in wire order (arrays
spread, char arrays raw), trailing zeros cut as MAVLink 2 does, the header, and the
CRC-16/MCRF4XX with the message's CRC extra. Packets are unsigned, as the simulator
sends them. tests/test_sitl_wire.py checks the bytes against ``pack`` for every message
the simulator builds.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from operator import attrgetter
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

_HEADER = struct.Struct("<BBBBBBBHB")
_CRC = struct.Struct("<H")
_FAST_CRC: Callable[[bytes, int], int] | None = getattr(mavlink, "mcrf4xx", None)
# Per message class: its field values in wire order, arrays spread.
_VALUES: dict[Any, Callable[[Any], tuple[Any, ...]]] = {}


def _values_of(kind: Any) -> Callable[[Any], tuple[Any, ...]]:
    names, spread = [], []
    for index, name in enumerate(kind.ordered_fieldnames):
        array = kind.array_lengths[index] > 0
        char = kind.fieldtypes[kind.fieldnames.index(name)] == "char"
        # pymavlink keeps a char array's bytes as _<name>_raw and its text as <name>.
        names.append(f"_{name}_raw" if char and array else name)
        spread.append(array and not char)
    get: Callable[[Any], Any] = attrgetter(*names)
    if len(names) == 1:  # attrgetter of one name gives the value, not a tuple
        only = get

        def get(msg: Any) -> tuple[Any, ...]:
            return (only(msg),)
    values: Callable[[Any], tuple[Any, ...]]
    if any(spread):
        def values(msg: Any) -> tuple[Any, ...]:
            out: list[Any] = []
            for value, wide in zip(get(msg), spread, strict=True):
                if wide:
                    out.extend(value)
                else:
                    out.append(value)
            return tuple(out)
    else:
        values = get
    _VALUES[kind] = values
    return values


def _crc(data: bytes) -> int:
    if _FAST_CRC is not None:
        return _FAST_CRC(data, 0xFFFF)
    crc: int = mavlink.x25crc(data).crc
    return crc


def encode(msg: Any, seq: int, system: int, component: int) -> bytes:
    """The MAVLink 2 packet of ``msg`` with sequence number ``seq`` from ``system`` and
    ``component``: the bytes ``msg.pack`` makes with a link in that state."""
    kind: Any = type(msg)
    values = (_VALUES.get(kind) or _values_of(kind))(msg)
    payload = msg.unpacker.pack(*values).rstrip(b"\0") or b"\0"
    msg_id = msg._header.msgId
    header = _HEADER.pack(253, len(payload), 0, 0, seq, system, component, msg_id & 0xFFFF,
                          msg_id >> 16)
    crc = _crc(header[1:] + payload + bytes((kind.crc_extra,)))
    return header + payload + _CRC.pack(crc)
