"""The live monitor's operator keys (no ROS graph): a key -> a command, stop and abort confirmed first."""

from __future__ import annotations

from folder_line.cli.monitor_view import MonitorState
from folder_line.cli.operator_keys import OperatorKeys


def test_operator_keys_send_commands_and_confirm_stop_and_abort() -> None:
    keys = OperatorKeys()
    assert keys.styled() == ('operator keys: h hold  u unhold  s start  x stop  r reset  c clear  a abort', '')
    assert keys.press('h') == 'hold' and keys.pending is None
    assert keys.press('z') is None  # not a key of a command
    assert keys.press('x') is None and keys.pending == 'stop'
    text, style = keys.styled()
    assert text.startswith('operator: stop the line? y: yes, any other key: no | ') and style == 'alert'
    assert keys.press('y') == 'stop' and keys.pending is None
    assert keys.press('a') is None and keys.press('n') is None
    assert keys.line == 'abort: cancelled' and keys.pending is None
    assert keys.press('a') is None and keys.press('Y') == 'abort'
    keys.sent('hold')
    assert keys.line == 'hold: sent, waiting for the supervisor'
    keys.answer('unhold', False, "'unhold' refused in state EXECUTE: legal only in HELD")
    assert keys.styled() == (
        "operator: unhold: refused: 'unhold' refused in state EXECUTE: legal only in HELD | "
        'h hold  u unhold  s start  x stop  r reset  c clear  a abort',
        'alert',
    )
    keys.no_service('clear')
    assert keys.line == 'clear: no supervisor service on this ROS domain; nothing sent'


def test_the_operator_row_is_shown_in_the_live_view_only() -> None:
    state = MonitorState(['/clock'])
    assert not any(line.startswith('operator') for line in state.render(160))  # the --once snapshot
    state.operator = OperatorKeys()
    lines = state.render(160)
    assert lines[2].startswith('operator keys: h hold')  # under the header, above the topics


def test_a_monitor_without_the_line_key_says_why_a_closed_line_may_not_answer() -> None:
    keyed, stranger = OperatorKeys(), OperatorKeys(keyed=False)
    keyed.sent('hold')
    stranger.sent('hold')
    assert keyed.line == 'hold: sent, waiting for the supervisor'
    assert stranger.line.startswith(keyed.line) and 'FOLDER_LINE_KEY' in stranger.line
