"""Fuzzing what comes from a vehicle: bytes into the link, absurd values into telemetry.

One link listens on loopback UDP, as ``tml run --connect udpin:...`` does, with the
adapter the engine reads (:class:`~tml.mavlink.adapter.MavlinkVehicle`) on it. Each case
sends it garbage bytes, frames cut short, frames with a wrong checksum, and well-formed
messages whose fields hold absurd values (NaN positions and attitudes, latitudes of 214
degrees, altitudes of 2,000 km, battery 127 % or -128 %, fix type 255 ...), then a
STATUSTEXT the link must still read: the receive thread must live on, and the vehicle's
state as the engine sees it must still be built. A third fuzzer puts such states into the
engine flying a mission on a fake vehicle: it may fail the mission, but only with tml's
own errors. Profiles and running more cases: docs/reliability.md.
"""

from __future__ import annotations

import math
import socket
import threading
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import pytest
from fake_vehicle import FakeVehicle
from fuzzing import fuzz_settings, memory_bound, time_bound
from hypothesis import given
from hypothesis import strategies as st

from tml.engine import Interpreter, Status
from tml.errors import TmlError
from tml.language.validation import validate_file
from tml.mavlink.adapter import MavlinkVehicle
from tml.mavlink.codec import mavlink
from tml.mavlink.link import Link

SYSTEM = 1
INTEGERS = {"int8_t": (-(1 << 7), (1 << 7) - 1), "uint8_t": (0, (1 << 8) - 1),
            "int16_t": (-(1 << 15), (1 << 15) - 1), "uint16_t": (0, (1 << 16) - 1),
            "int32_t": (-(1 << 31), (1 << 31) - 1), "uint32_t": (0, (1 << 32) - 1),
            "int64_t": (-(1 << 63), (1 << 63) - 1), "uint64_t": (0, (1 << 64) - 1)}
MESSAGES = ("HEARTBEAT", "GLOBAL_POSITION_INT", "LOCAL_POSITION_NED", "HOME_POSITION",
            "ATTITUDE", "SYS_STATUS", "BATTERY_STATUS", "EXTENDED_SYS_STATE", "GPS_RAW_INT",
            "EKF_STATUS_REPORT", "MISSION_CURRENT", "MISSION_ITEM_REACHED", "STATUSTEXT",
            "COMMAND_ACK", "MISSION_REQUEST_INT", "MISSION_ACK", "MISSION_COUNT",
            "MISSION_ITEM_INT", "PARAM_VALUE", "NAMED_VALUE_FLOAT", "NAMED_VALUE_INT",
            "DEBUG_VECT", "VFR_HUD", "AUTOPILOT_VERSION")


def _field(kind: str, length: int) -> st.SearchStrategy[Any]:
    if kind == "char":
        return st.binary(max_size=length)
    if kind in ("float", "double"):
        one: st.SearchStrategy[Any] = st.floats(width=32 if kind == "float" else 64)
    else:
        low, high = INTEGERS[kind]
        one = st.one_of(st.sampled_from((low, high, 0, -1 if low else 1)),
                        st.integers(low, high))
    return st.lists(one, min_size=length, max_size=length) if length else one


@st.composite
def absurd_message(draw: st.DrawFn) -> bytes:
    """One well-formed frame from the vehicle's autopilot, its fields anything they can hold."""
    name = draw(st.sampled_from(MESSAGES))
    cls = mavlink.mavlink_map[getattr(mavlink, f"MAVLINK_MSG_ID_{name}")]
    lengths = dict(zip(cls.ordered_fieldnames, cls.array_lengths, strict=True))
    values = [draw(_field(kind, lengths[name]))
              for name, kind in zip(cls.fieldnames, cls.fieldtypes, strict=True)]
    component = draw(st.sampled_from((1, 1, 1, 191, 0)))
    encoder = mavlink.MAVLink(None, srcSystem=SYSTEM, srcComponent=component)
    encoder.seq = draw(st.integers(0, 255))
    return bytes(cls(*values).pack(encoder))


@st.composite
def hostile_bytes(draw: st.DrawFn) -> bytes:
    """Garbage, cut frames, frames with a bad checksum or a bad length, and absurd values."""
    parts = []
    for _ in range(draw(st.integers(1, 6))):
        frame = draw(absurd_message())
        how = draw(st.sampled_from(("whole", "cut", "crc", "flip", "garbage", "length")))
        if how == "cut":
            frame = frame[:draw(st.integers(1, len(frame) - 1))]
        elif how == "crc":
            frame = frame[:-2] + bytes(b ^ 0xFF for b in frame[-2:])
        elif how == "flip":
            index = draw(st.integers(0, len(frame) - 1))
            frame = frame[:index] + bytes([frame[index] ^ draw(st.integers(1, 255))]) + \
                frame[index + 1:]
        elif how == "garbage":
            frame = draw(st.binary(min_size=1, max_size=300))
        elif how == "length":
            frame = frame[:1] + bytes([draw(st.integers(0, 255))]) + frame[2:]
        parts.append(frame)
    return b"".join(parts)


class Harness:
    """A link on udpin 127.0.0.1, the adapter on it, and a socket playing the vehicle."""

    def __init__(self) -> None:
        self.link = Link("udpin:127.0.0.1:0", system_ids=[SYSTEM]).start()
        address = self.link.local_address
        assert address is not None
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.connect(address)
        self.encoder = mavlink.MAVLink(None, srcSystem=SYSTEM, srcComponent=1)
        self.syncs = 0
        self.send(self.encoder.heartbeat_encode(
            mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 0).pack(
                self.encoder))
        self.vehicle = MavlinkVehicle(self.link, SYSTEM, connect_timeout=5.0)

    def send(self, data: bytes) -> None:
        for start in range(0, len(data), 1024):  # one datagram per kilobyte
            self.sock.send(data[start:start + 1024])

    def sync(self) -> None:
        """Flush what a cut frame left in the parser, then wait until a STATUSTEXT is read."""
        self.syncs += 1
        text = f"sync {self.syncs}"
        self.send(bytes(300))  # completes any frame the parser still waits for
        self.send(self.encoder.statustext_encode(6, text.encode()).pack(self.encoder))
        self.link.wait_telemetry(
            SYSTEM, lambda t: bool(t.status_texts) and t.status_texts[-1].text == text,
            timeout=5.0, lost_ok=True)

    def close(self) -> None:
        self.vehicle.close()
        self.link.close()
        self.sock.close()


@pytest.fixture
def harness() -> Iterator[Harness]:
    failures: list[threading.ExceptHookArgs] = []
    previous = threading.excepthook
    threading.excepthook = failures.append
    made = Harness()
    try:
        yield made
    finally:
        made.close()
        threading.excepthook = previous
    assert not failures, [f"{f.thread}: {f.exc_type.__name__}: {f.exc_value}"
                          for f in failures]


def test_hostile_bytes_never_stop_the_link(harness: Harness) -> None:
    @fuzz_settings(1000)
    @given(hostile_bytes())
    def case(data: bytes) -> None:
        with time_bound(), memory_bound():
            harness.send(data)
            harness.sync()
            assert harness.link.serving
            state = harness.vehicle.state()
            assert state.vehicle_id == SYSTEM

    case()
    # The cases reached the parser, and well-formed absurd messages reached the telemetry.
    assert harness.link.stats.bad_data > 0
    assert harness.link.telemetry(SYSTEM).received > harness.syncs + 10


ABSURD = st.one_of(st.just(math.nan), st.just(math.inf), st.just(-math.inf),
                   st.floats(-1e12, 1e12), st.just(1e308))


@st.composite
def absurd_state(draw: st.DrawFn, state: Any) -> Any:
    """``state`` with some of what telemetry says replaced by what no vehicle reports."""
    changes: dict[str, Any] = {}
    if draw(st.booleans()):
        changes["position"] = (draw(ABSURD), draw(ABSURD), draw(ABSURD))
    if draw(st.booleans()):
        changes["battery"] = draw(st.sampled_from((255.0, 127.0, -128.0, math.nan, None)))
    if draw(st.booleans()):
        changes["heading"] = draw(ABSURD)
    if draw(st.booleans()):
        changes["gps_fix"] = draw(st.sampled_from((255, -1, 0)))
    if draw(st.booleans()):
        changes["ground_speed"] = draw(ABSURD)
    if draw(st.booleans()):
        changes["mode"] = draw(st.sampled_from(("", "Mode(0x7fffffff)", "LAND", "\x1b[2J")))
    return replace(state, **changes)


MISSION = (b'<mission name="m"><task name="Take off"><action name="TAKE_OFF">'
           b'<argument name="altitude" value="5"/></action></task>'
           b'<task name="Go"><action name="GO_TO_POINT"><argument name="coordinates" '
           b'value="(20, 0, 5)"/></action></task>'
           b'<task name="Land"><action name="LAND"/></task>'
           b'<event_handling><event name="Low battery"><condition '
           b'parameter="BATTERY_CHARGE_PERCENTAGE" comparison="less than" value="30"/>'
           b'<action name="LAND"/><termination mode="ABORT_MISSION"/></event>'
           b'</event_handling></mission>')


@fuzz_settings(200)
@given(st.data())
def test_absurd_telemetry_never_crashes_the_engine(data: st.DataObject) -> None:
    result = validate_file("m.xml", MISSION)
    assert result.errors == [] and result.mission is not None
    vehicle = FakeVehicle()
    engine = Interpreter(result.mission, [vehicle.vehicle_id])
    absurd_from = data.draw(st.integers(0, 120), label="first absurd step")
    with time_bound():
        try:
            out = engine.start(0.0, {1: vehicle.state()})
            now = 0.0
            for step in range(150):
                for request in out.requests:
                    vehicle.submit(request)
                if engine.status is not Status.RUNNING:
                    break
                now = round(now + 0.1, 6)
                vehicle.advance(0.1)
                state = vehicle.state()
                if step >= absurd_from:
                    state = data.draw(absurd_state(state))
                out = engine.step(now, {1: state}, {1: vehicle.poll()})
        except TmlError:
            pass
