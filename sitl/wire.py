"""MAVLink 2 packets from pymavlink messages, at a quarter of ``msg.pack``'s cost.

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
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

_HEADER = struct.Struct("<BBBBBBBHB")
_CRC = struct.Struct("<H")
# Per message class: (attribute, spread) for each field in wire order.
_LAYOUTS: dict[Any, tuple[tuple[str, bool], ...]] = {}


def _layout(kind: Any) -> tuple[tuple[str, bool], ...]:
    fields = []
    for index, name in enumerate(kind.ordered_fieldnames):
        array = kind.array_lengths[index] > 0
        char = kind.fieldtypes[kind.fieldnames.index(name)] == "char"
        # pymavlink keeps a char array's bytes as _<name>_raw and its text as <name>.
        fields.append((f"_{name}_raw" if char and array else name, array and not char))
    layout = tuple(fields)
    _LAYOUTS[kind] = layout
    return layout


def encode(msg: Any, seq: int, system: int, component: int) -> bytes:
    """The MAVLink 2 packet of ``msg`` with sequence number ``seq`` from ``system`` and
    ``component``: the bytes ``msg.pack`` makes with a link in that state."""
    kind: Any = type(msg)
    values: list[Any] = []
    for name, spread in _LAYOUTS.get(kind) or _layout(kind):
        if spread:
            values.extend(getattr(msg, name))
        else:
            values.append(getattr(msg, name))
    payload = msg.unpacker.pack(*values).rstrip(b"\0") or b"\0"
    msg_id = msg._header.msgId
    header = _HEADER.pack(253, len(payload), 0, 0, seq, system, component, msg_id & 0xFFFF,
                          msg_id >> 16)
    crc = mavlink.x25crc(header[1:] + payload + bytes((kind.crc_extra,))).crc
    return header + payload + _CRC.pack(crc)
