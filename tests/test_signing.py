"""Signing keys from a file or the environment (tml.signing)."""

from __future__ import annotations

import hashlib
from pathlib import Path

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
