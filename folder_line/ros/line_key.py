"""The line's key: which processes make up one line, and the DDS partition that keeps the rest out.

Every process of a line (``folder-line run``, its node processes, ``ros2 launch``'s nodes,
the nodes on other hosts, and the operator's ``folder-line hold``/``tune``/``monitor``)
reads the key from :data:`KEY_VARIABLE`. :func:`folder_line.ros.dds_profile.use_line_profile`
turns it into a DDS partition (:func:`partition_name`) for the process's readers and writers:
the line's readers hear only writers of that partition, so a node, a ``ros2 topic pub`` or a
second line without the key reaches none of them; the line's writers are in the default
partition too, so ``ros2 topic echo``, ``ros2 bag record`` and Foxglove still see every topic.
The partition is derived from the key and is not the key: but it travels in clear text in DDS
discovery, so it isolates a line from strangers and other lines on the domain, not from someone
who reads the network's packets (the docs say what does).
"""

from __future__ import annotations

import hashlib
import secrets
from collections.abc import Mapping, MutableMapping
from typing import Final

from folder_line.errors import ParameterError

__all__ = ['KEY_BYTES', 'KEY_VARIABLE', 'ensure_key', 'new_key', 'partition_name', 'read_key']

KEY_VARIABLE: Final = 'FOLDER_LINE_KEY'
"""The environment variable that holds the line's key, in hex."""

KEY_BYTES: Final = 16
"""Bytes of a new key (:func:`new_key`), and the fewest a key may have."""

_PARTITION_PREFIX: Final = 'folder_line_'


def new_key() -> str:
    """A fresh random key, :data:`KEY_BYTES` bytes in hex."""
    return secrets.token_hex(KEY_BYTES)


def read_key(environ: Mapping[str, str]) -> bytes | None:
    """The key in ``environ`` (:data:`KEY_VARIABLE`), or None when it is unset or empty.

    Raises
    ------
    ParameterError
        The value is not hex, or is shorter than :data:`KEY_BYTES` bytes.
    """
    text = environ.get(KEY_VARIABLE, '').strip()
    if not text:
        return None
    try:
        key = bytes.fromhex(text)
    except ValueError:
        key = b''
    if len(key) < KEY_BYTES:
        reason = (
            f'not a line key: it takes {2 * KEY_BYTES} or more hex digits '
            "(make one with: python3 -c 'import secrets; print(secrets.token_hex(16))')"
        )
        raise ParameterError(KEY_VARIABLE, text, reason)
    return key


def ensure_key(environ: MutableMapping[str, str]) -> tuple[bytes, bool]:
    """The key in ``environ``, set to a :func:`new_key` first if there is none.

    Returns
    -------
    key : bytes
    made : bool
        True when the key was made here (the caller tells the operator).

    Raises
    ------
    ParameterError
        ``environ`` holds a key that is not one (:func:`read_key`).
    """
    key = read_key(environ)
    if key is not None:
        return key, False
    environ[KEY_VARIABLE] = new_key()
    return bytes.fromhex(environ[KEY_VARIABLE]), True


def partition_name(key: bytes) -> str:
    """The DDS partition of the line with ``key``: ``folder_line_`` and 16 hex digits of a keyed hash.

    One-way: the partition, which DDS discovery sends in clear, does not give away the key.
    """
    digest = hashlib.blake2b(b'partition', key=key[:64], digest_size=8).hexdigest()
    return _PARTITION_PREFIX + digest
