"""Messages of the line's protocol as a test forges them, signed with the test process's line key
(:mod:`folder_line.ros.signing`), so that a test reaches the check it means to reach."""

from __future__ import annotations

from typing import Any

from rclpy.parameter import Parameter
from sensor_msgs.msg import TimeReference

from folder_line.ros.parameters import signed_change
from folder_line.ros.signing import line_signer, open_text, sign_text
from folder_line.ros.time_msg import ns_to_time_msg


def time_reference(frame: str, stamp_ns: int, source: str, kind: str, time_ref_ns: int | None = None) -> TimeReference:
    """A ``TimeReference`` from ``frame`` stamped ``stamp_ns`` (``time_ref``: ``time_ref_ns``, default the
    stamp) whose ``source`` is signed as a message of ``kind`` ('grant', 'progress', 'tick_done',
    'command')."""
    msg = TimeReference()
    msg.header.frame_id = frame
    msg.header.stamp = ns_to_time_msg(stamp_ns)
    msg.time_ref = ns_to_time_msg(stamp_ns if time_ref_ns is None else time_ref_ns)
    msg.source = sign_text(source, kind, frame.split('\x00', 1)[0], msg.header.stamp, msg.time_ref)
    return msg


def signed(node: str, parameters: list[Parameter[Any]]) -> list[Parameter[Any]]:
    """``parameters`` for node ``node`` (its name) with the signature of the change, to set at once
    (``set_parameters_atomically``), as ``folder-line tune`` does (the test process has a key)."""
    assert line_signer().keyed
    return signed_change(node, parameters)


def command_text(msg: TimeReference) -> str:
    """The text of a drive command as the supervisor published it, its signature checked."""
    return open_text(msg.source, 'command', msg.header.frame_id, msg.header.stamp, msg.time_ref)
