"""MAVLink 2 signing keys: where they come from (a file or an environment variable, never
the command line, where any user of the machine reads them in the process list).

A key is 32 bytes. The text that gives it is 64 hexadecimal digits, the key itself, or
else a passphrase whose SHA-256 is the key, as MAVProxy's ``signing setup PASSPHRASE``
makes it: the same passphrase signs in MAVProxy, QGroundControl and tml alike.
"""

from __future__ import annotations

import hashlib
import os
import string
import time
from collections.abc import Mapping
from typing import Any

from tml.errors import TmlError

ENVIRONMENT = "TML_SIGNING_KEY"
"""The environment variable read for a key when no key file is given."""


def key_from_text(text: str) -> bytes:
    """The key a text gives (see the module docstring); TmlError for an empty one."""
    text = text.strip()
    if not text:
        raise TmlError("an empty signing key")
    if len(text) == 64 and all(c in string.hexdigits for c in text):
        return bytes.fromhex(text)
    return hashlib.sha256(text.encode()).digest()


def signing_key(path: str | None, environ: Mapping[str, str] = os.environ) -> bytes | None:
    """The key of the file at ``path``, else of :data:`ENVIRONMENT`, else None (no signing).

    Raises OSError when the file cannot be read, TmlError when it gives no key."""
    if path is not None:
        with open(path, encoding="utf-8") as file:
            return key_from_text(file.read(4096))
    text = environ.get(ENVIRONMENT)
    return None if text is None else key_from_text(text)


EPOCH = 1420070400
"""1 January 2015 (Unix time), from which MAVLink 2 signing time stamps count (10 us units)."""


def signature_valid(key: bytes, frame: bytes | bytearray) -> bool:
    """Whether a signed MAVLink 2 frame's signature (its last 6 bytes) is the key's: the
    first 6 bytes of SHA-256 over the key and the frame up to the signature."""
    return hashlib.sha256(bytes(key) + bytes(frame[:-6])).digest()[:6] == bytes(frame[-6:])


def signature_first(parser: Any) -> None:
    """Make a pymavlink parser check a frame's signature before its time stamp.

    pymavlink's ``check_signature`` stores a stream's time stamp before it compares the
    signature: one keyless frame stamped a day ahead then makes every genuine frame of
    that stream "old", and the link is lost. The MAVLink signing specification (and
    ArduPilot) accept a time stamp only from a frame whose signature holds."""
    check = parser.check_signature

    def checked(frame: bytearray, system: int, component: int) -> bool:
        key = parser.signing.secret_key
        if key is None or not signature_valid(key, frame):
            return False
        return bool(check(frame, system, component))

    parser.check_signature = checked


def timestamp_now(now: float | None = None) -> int:
    """The signing time stamp of Unix time ``now`` (default: the system's clock)."""
    return int(((time.time() if now is None else now) - EPOCH) * 1e5)
