"""MAVLink 2 packets from pymavlink messages, or straight from a message's arguments.

The simulator encodes every telemetry message of every vehicle, several hundred a
vehicle-second when a client asks for all streams, and pymavlink's ``pack`` spends most
of its time outside the payload: a header object, a CRC object, a bytearray copied to
bytes, a version check, per packet (docs/performance.md). :func:`encode` builds the same
bytes directly: the payload with the message's own ``struct`` in wire order (arrays
spread, char arrays raw), trailing zeros cut as MAVLink 2 does, the header, and the
CRC-16/MCRF4XX with the message's CRC extra. Packets are unsigned, as the simulator
sends them.

Streamed telemetry need not become a pymavlink message at all: a :class:`Fields` holds a
message's class and the arguments its constructor would take, and :func:`encode` packs
those arguments as the message would pack them (the extension fields left out take the
constructor's defaults), with a function written for the message's class on first use
(:data:`ENCODERS`: the arguments read by index in wire order, header and CRC inline).
tests/test_sitl_wire.py checks both against ``pack`` for every message of the dialect.
"""

from __future__ import annotations

import inspect
import struct
from collections.abc import Callable
from operator import attrgetter
from typing import Any, NamedTuple

from pymavlink.dialects.v20 import ardupilotmega as mavlink

_HEADER = struct.Struct("<BBBBBBBHB")
_CORE_PACK = struct.Struct("<BBBBBBHB").pack  # the header after its first byte (253)
_CRC = struct.Struct("<H")
_HEADER_PACK = _HEADER.pack
_CRC_PACK = _CRC.pack
_FAST_CRC: Callable[[bytes, int], int] | None = getattr(mavlink, "mcrf4xx", None)
# Per message class: its payload's pack, its id's low 16 and high 8 bits, its CRC extra.
_PLANS: dict[Any, tuple[Callable[..., bytes], int, int, bytes]] = {}
Values = Callable[[Any], tuple[Any, ...]]
# Per message class: a message's field values in wire order, arrays spread.
_VALUES: dict[Any, Values] = {}
# A message class's packet from the constructor's arguments, a sequence number and the
# sender (system, component).
Encoder = Callable[[tuple[Any, ...], int, int, int], bytes]


class _Encoders(dict[Any, Encoder]):
    def __missing__(self, kind: Any) -> Encoder:
        encoder = self[kind] = _arguments_encoder(kind)
        return encoder


ENCODERS: dict[Any, Encoder] = _Encoders()
"""Per message class, its :data:`Encoder` (written on first use): ``ENCODERS[kind](args,
seq, system, component)`` is ``encode(Fields(kind, args), seq, system, component)``."""


class Fields(NamedTuple):
    """A message not built: its pymavlink class and its constructor's arguments (the
    trailing extension fields may be left out)."""

    kind: Any
    args: tuple[Any, ...]

    def message(self) -> Any:
        """The pymavlink message these arguments make."""
        return self.kind(*self.args)


def _wire_order(kind: Any) -> tuple[list[str], list[bool]]:
    """The fields in wire order, each with whether it is an array to spread (a char
    array is not: it packs as one bytes value)."""
    names, spread = [], []
    for index, name in enumerate(kind.ordered_fieldnames):
        array = kind.array_lengths[index] > 0
        char = kind.fieldtypes[kind.fieldnames.index(name)] == "char"
        names.append(name)
        spread.append(array and not char)
    return names, spread


def _spreading(get: Callable[[Any], Any], count: int, spread: list[bool]) -> Values:
    """``get``'s values as one flat tuple: a tuple even of one value, arrays spread."""
    if count == 1:  # a getter of one item gives the value, not a tuple
        def one(source: Any) -> tuple[Any, ...]:
            value = get(source)
            return tuple(value) if spread[0] else (value,)
        return one
    if not any(spread):
        return get
    # Spread from the last array back, so that the earlier ones keep their positions.
    arrays = [index for index, wide in enumerate(spread) if wide][::-1]

    def values(source: Any) -> tuple[Any, ...]:
        out = list(get(source))
        for index in arrays:
            out[index:index + 1] = out[index]
        return tuple(out)
    return values


def _values_of(kind: Any) -> Values:
    names, spread = _wire_order(kind)
    char_arrays = {name for name, wide in zip(names, spread, strict=True) if not wide
                   and kind.array_lengths[kind.ordered_fieldnames.index(name)] > 0}
    # pymavlink keeps a char array's bytes as _<name>_raw and its text as <name>.
    attributes = [f"_{name}_raw" if name in char_arrays else name for name in names]
    values = _VALUES[kind] = _spreading(attrgetter(*attributes), len(names), spread)
    return values


def _arguments_source(kind: Any) -> tuple[str, tuple[Any, ...]]:
    """The source of ``kind``'s encoder from its constructor's arguments, and the
    defaults of the extension fields it reads."""
    names, spread = _wire_order(kind)
    parameters = list(inspect.signature(kind.__init__).parameters.values())[1:]
    if [p.name for p in parameters] != list(kind.fieldnames):
        raise TypeError(f"{kind.__name__}: constructor arguments are not its fields")
    defaults = tuple(p.default for p in parameters if p.default is not p.empty)
    required = len(parameters) - len(defaults)

    def values(given: int) -> str:
        """The arguments in wire order, read by index, arrays spread; from the first
        ``given`` arguments, the extensions after them their defaults."""
        return ", ".join(
            f"{'*' if wide else ''}"
            + (f"a[{index}]" if index < given else f"defaults[{index - required}]")
            for index, wide in ((kind.fieldnames.index(name), wide)
                                for name, wide in zip(names, spread, strict=True)))
    if defaults:  # all the arguments, none of the extensions, or some of them
        body = (
            f"    n = len(a)\n"
            f"    if n == {len(parameters)}:\n"
            f"        payload = pack({values(len(parameters))})\n"
            f"    elif n == {required}:\n"
            f"        payload = pack({values(required)})\n"
            f"    else:\n"
            f"        a = a + defaults[n - {required}:]\n"
            f"        payload = pack({values(len(parameters))})\n"
        )
    else:
        body = f"    payload = pack({values(len(parameters))})\n"
    source = (
        "def encode(a, seq, system, component):\n"
        + body +
        "    payload = payload.rstrip(b'\\0') or b'\\0'\n"
        f"    core = header(len(payload), 0, 0, seq, system, component, {kind.id & 0xFFFF},"
        f" {kind.id >> 16}) + payload\n"
        "    return b'\\xfd' + core + crc_pack(crc(core + extra, 0xFFFF))\n"
    )
    return source, defaults


def _arguments_encoder(kind: Any) -> Encoder:
    """``kind``'s packet straight from its constructor's arguments: a function written
    for the message (its fields read by index in wire order, the header and the CRC
    inline), since streamed telemetry is most of what the simulator does."""
    source, defaults = _arguments_source(kind)
    scope = {"defaults": defaults, "pack": kind.unpacker.pack, "header": _CORE_PACK,
             "crc_pack": _CRC_PACK, "crc": _crc, "extra": bytes((kind.crc_extra,))}
    exec(compile(source, f"<sitl.wire encoder of {kind.__name__}>", "exec"), scope)
    encoder: Encoder = scope["encode"]
    return encoder


def _slow_crc(data: bytes, initial: int) -> int:  # x25crc starts from 0xFFFF, as here
    crc: int = mavlink.x25crc(data).crc
    return crc


# CRC-16/MCRF4XX of data from an initial 0xFFFF: fastcrc's when pymavlink has it.
_crc: Callable[[bytes, int], int] = _FAST_CRC if _FAST_CRC is not None else _slow_crc


def encode(msg: Any, seq: int, system: int, component: int) -> bytes:
    """The MAVLink 2 packet of ``msg`` (a pymavlink message or :class:`Fields`) with
    sequence number ``seq`` from ``system`` and ``component``: the bytes ``msg.pack``
    makes with a link in that state."""
    if type(msg) is Fields:
        kind: Any = msg.kind
        return ENCODERS[kind](msg.args, seq, system, component)
    kind = type(msg)
    values = (_VALUES.get(kind) or _values_of(kind))(msg)
    pack, low, high, extra = _PLANS.get(kind) or _plan_of(kind)
    payload = pack(*values).rstrip(b"\0") or b"\0"
    header = _HEADER_PACK(253, len(payload), 0, 0, seq, system, component, low, high)
    return header + payload + _CRC_PACK(_crc(header[1:] + payload + extra, 0xFFFF))


def _plan_of(kind: Any) -> tuple[Callable[..., bytes], int, int, bytes]:
    plan = _PLANS[kind] = (kind.unpacker.pack, kind.id & 0xFFFF, kind.id >> 16,
                           bytes((kind.crc_extra,)))
    return plan
