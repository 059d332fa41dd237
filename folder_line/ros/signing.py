"""The line's signatures: only a holder of the line key grants time, acknowledges a tick, commands the
drives, forwards a tuning, announces the participants or asks for a change.

The partition (:mod:`folder_line.ros.line_key`) keeps strangers out, but its name travels in clear in
DDS discovery. These signatures hold against someone who learnt it: a keyed hash (HMAC-SHA256, 128 bits
kept) of each control message's text and of the fields around it, under a signing key derived from the
line key (never the key itself). The docs' "Who may command the line" says what they cover and what not.

* **Control messages** (:func:`sign_text`, :func:`open_text`): the grants, the acknowledgements
  (``progress``, ``tick_done``), the announcement, the drive commands and the tunings a node forwards
  carry `` sig=<32 hex>`` at the end of their text, over the text, the message's kind, its
  ``frame_id`` and its stamps. A reader of a keyed line refuses a message without a valid one.
* **Requests** (:func:`sign_request`, :class:`RequestGuard`): on a keyed line a node's parameters change
  at run time only in a batch that carries :data:`SIGNATURE_PARAMETER`, a signature over the node's name,
  the batch's other values, a wall time and a nonce. A request older or newer than
  :data:`REQUEST_WINDOW` s, or seen before, is refused: a request read off the network cannot be played
  again.

A line without a key (an open line) signs and checks nothing. This module needs no ROS: a node installs
the request check with :func:`folder_line.ros.parameters.guard_changes`.
"""

from __future__ import annotations

import functools
import hashlib
import hmac
import os
import secrets
import time
from collections.abc import Iterable
from typing import Final

from folder_line.ros.line_key import read_key
from folder_line.ros.message_fields import StampLike

__all__ = [
    'REQUEST_WINDOW',
    'SIGNATURE_FIELD',
    'SIGNATURE_PARAMETER',
    'RequestGuard',
    'Signer',
    'line_signer',
    'open_text',
    'sign_request',
    'sign_text',
    'stamp_text',
    'without_signature',
]

SIGNATURE_FIELD: Final = ' sig='
"""What separates a control message's text from its signature."""

SIGNATURE_PARAMETER: Final = 'line_signature'
"""The parameter that carries a request's signature (:func:`sign_request`)."""

REQUEST_WINDOW: Final = 30.0
"""Wall s a signed request stays valid either side of its time (the hosts' clocks agree to within it)."""

_DIGEST_BYTES: Final = 16


class Signer:
    """Signs and checks with one line key (None: an open line, nothing signed or checked)."""

    def __init__(self, key: bytes | None) -> None:
        self._key = None if key is None else hashlib.blake2b(b'signing', key=key[:64], digest_size=32).digest()

    @property
    def keyed(self) -> bool:
        """True on a keyed line."""
        return self._key is not None

    def digest(self, *parts: str) -> str:
        """The hex signature of ``parts`` (a keyed line only)."""
        assert self._key is not None
        data = '\x1f'.join(parts).encode()
        return hmac.digest(self._key, data, 'sha256')[:_DIGEST_BYTES].hex()

    def sign(self, text: str, *context: str) -> str:
        """``text`` with its signature over it and ``context`` appended (unchanged on an open line)."""
        if self._key is None:
            return text
        return f'{text}{SIGNATURE_FIELD}{self.digest(text, *context)}'

    def open(self, text: str, *context: str) -> str:
        """``text`` without its signature, checked against ``context`` (unchanged on an open line).

        Raises ``ValueError`` with the reason when the signature is missing or wrong.
        """
        if self._key is None:
            return text
        body, sep, signature = text.rpartition(SIGNATURE_FIELD)
        if not sep:
            raise ValueError('unsigned, on a keyed line (the sender lacks the line key)')
        if not hmac.compare_digest(signature, self.digest(body, *context)):
            raise ValueError('signature does not match (a sender without the line key, or a changed message)')
        return body


@functools.cache
def line_signer() -> Signer:
    """This process's signer, from :data:`~folder_line.ros.line_key.KEY_VARIABLE` (read once)."""
    return Signer(read_key(os.environ))


def stamp_text(stamp: StampLike) -> str:
    """``builtin_interfaces/Time`` as ``'sec.nanosec'`` (rclpy's message or rosbags')."""
    return f'{stamp.sec}.{stamp.nanosec}'


def sign_text(text: str, kind: str, frame_id: str = '', *stamps: StampLike) -> str:
    """:meth:`Signer.sign` of ``text`` under this process's key, over ``kind``, ``frame_id`` and ``stamps``."""
    return line_signer().sign(text, kind, frame_id, *map(stamp_text, stamps))


def open_text(text: str, kind: str, frame_id: str = '', *stamps: StampLike) -> str:
    """:meth:`Signer.open`, the inverse of :func:`sign_text` (``ValueError`` with the reason)."""
    return line_signer().open(text, kind, frame_id, *map(stamp_text, stamps))


def without_signature(text: str) -> str:
    """``text`` without a signature it may end with, unchecked: for display by a reader without the key."""
    body, sep, signature = text.rpartition(SIGNATURE_FIELD)
    return body if sep and len(signature) == 2 * _DIGEST_BYTES and ' ' not in signature else text


def _value_text(value: object) -> str:
    # a number as a float: a node may take an integer for a float parameter before the signature is checked
    if isinstance(value, int | float) and not isinstance(value, bool):
        return repr(float(value))
    return repr(list(value) if isinstance(value, tuple | list) else value)


def _request_text(node: str, values: Iterable[tuple[str, object]]) -> str:
    return '\n'.join(sorted(f'{name}={_value_text(value)}' for name, value in values)) + f'\n@{node}'


def sign_request(node: str, values: Iterable[tuple[str, object]], signer: Signer | None = None) -> str:
    """The value of :data:`SIGNATURE_PARAMETER` for setting ``values`` (name, value) on node ``node``
    (its name, without namespace) now: ``'<wall ns>.<nonce>.<signature>'``."""
    signer = line_signer() if signer is None else signer
    head = f'{time.time_ns()}.{secrets.token_hex(8)}'
    return f'{head}.{signer.digest(head, _request_text(node, values))}'


class RequestGuard:
    """Checks the signed requests of one node (:func:`sign_request`), each once.

    Remembers the nonces it took for :data:`REQUEST_WINDOW` s, so its memory is bounded by the rate of
    requests, not by how long the line runs.
    """

    def __init__(self, node: str, signer: Signer | None = None) -> None:
        self.node = node
        self.signer = line_signer() if signer is None else signer
        self._seen: dict[str, float] = {}

    def check(self, signature: object, values: Iterable[tuple[str, object]]) -> str:
        """'' when ``signature`` signs ``values`` for this node, now and for the first time; else why not."""
        if not self.signer.keyed:
            return ''
        if not isinstance(signature, str) or not signature:
            return (
                f'this line is keyed: a change at run time must be signed with the line key '
                f'({SIGNATURE_PARAMETER}; folder-line tune and hold sign theirs)'
            )
        parts = signature.split('.')
        if len(parts) != 3 or not parts[0].isdigit():
            return f'{SIGNATURE_PARAMETER}={signature[:60]!r}: not <wall ns>.<nonce>.<signature>'
        now = time.time()
        age = now - int(parts[0]) / 1e9
        if abs(age) > REQUEST_WINDOW:
            return f'{SIGNATURE_PARAMETER}: signed {age:.0f} s ago (at most {REQUEST_WINDOW:g} s either way)'
        head = f'{parts[0]}.{parts[1]}'
        if not hmac.compare_digest(parts[2], self.signer.digest(head, _request_text(self.node, values))):
            return f'{SIGNATURE_PARAMETER}: does not sign this change for {self.node} with the line key'
        self._seen = {n: t for n, t in self._seen.items() if now - t <= 2 * REQUEST_WINDOW}
        if head in self._seen:
            return f'{SIGNATURE_PARAMETER}: a request already taken (played again?)'
        self._seen[head] = now
        return ''
