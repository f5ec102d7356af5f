"""Signing keys from a file or the environment (tml.signing)."""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

import pytest

from tml.errors import TmlError
from tml.signing import key_from_text, signing_key


def test_64_hex_digits_are_the_key_and_anything_else_a_passphrase() -> None:
    assert key_from_text("00" * 16 + "ff" * 16) == bytes(16) + b"\xff" * 16
    assert key_from_text(" secret \n") == hashlib.sha256(b"secret").digest()
    with pytest.raises(TmlError, match="empty"):
        key_from_text("  \n")


def test_the_file_comes_before_the_environment(tmp_path: Path) -> None:
    path = tmp_path / "key"
    path.write_text("from the file")
    environ = {"TML_SIGNING_KEY": "from the environment"}
    assert signing_key(str(path), environ) == hashlib.sha256(b"from the file").digest()
    assert signing_key(None, environ) == hashlib.sha256(b"from the environment").digest()
    assert signing_key(None, {}) is None


KEY = hashlib.sha256(b"field laptop").digest()


def _signed_frame(key: bytes, timestamp: int, system: int = 1) -> bytes:
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    sender = mavlink.MAVLink(None, system, 1)
    sender.signing.secret_key = key
    sender.signing.sign_outgoing = True
    sender.signing.timestamp = timestamp
    return bytes(sender.heartbeat_encode(2, 3, 0, 4, 4).pack(sender))


def _parser() -> object:
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    parser = mavlink.MAVLink(None)
    parser.robust_parsing = True
    parser.signing.secret_key = KEY
    parser.signing.allow_unsigned_callback = lambda _mav, _msgid: False
    return parser


def test_a_frame_with_a_wrong_signature_moves_no_stream_time_stamp() -> None:
    from tml.signing import signature_first, signature_valid, timestamp_now

    now = timestamp_now()
    day_ahead = _signed_frame(hashlib.sha256(b"not the key").digest(), now + 86_400 * 10**5)
    genuine = _signed_frame(KEY, now)
    assert signature_valid(KEY, genuine) and not signature_valid(KEY, day_ahead)
    # pymavlink as it is: the forged frame's time stamp is stored, the genuine one refused.
    def taken(parser: Any) -> list[str]:
        found = parser.parse_buffer(day_ahead + genuine) or []
        return [m.get_type() for m in found if m.get_type() != "BAD_DATA"]

    plain: Any = _parser()
    assert taken(plain) == []
    checked: Any = _parser()
    signature_first(checked)
    assert taken(checked) == ["HEARTBEAT"]
    assert checked.signing.badsig_count == 1


def test_the_simulators_signing_time_stamps_follow_its_clock(
        monkeypatch: pytest.MonkeyPatch) -> None:
    import sitl.server
    from sitl.server import Simulator
    from tml.signing import timestamp_now

    clock = [timestamp_now()]
    monkeypatch.setattr(sitl.server, "timestamp_now", lambda: clock[0])
    with Simulator(vehicles=1, tcp_base_port=0, realtime=False, signing_key=KEY) as sim:
        from pymavlink.dialects.v20 import ardupilotmega as mavlink

        endpoint = sim._endpoints[0]
        first = endpoint.encode(mavlink.MAVLink_heartbeat_message(2, 3, 0, 4, 4, 3))
        clock[0] += 120 * 10**5  # two minutes and only a few frames later
        later = endpoint.encode(mavlink.MAVLink_heartbeat_message(2, 3, 0, 4, 4, 3))
    stamp = [int.from_bytes(frame[-12:-6], "little") for frame in (first, later)]
    assert stamp[1] >= clock[0] > stamp[0]
