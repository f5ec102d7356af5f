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
from collections.abc import Mapping

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
