"""Who may command the line: the signatures of the line's key (:mod:`folder_line.ros.signing`).

* Unit: a signed text opens under the same key and context only; a request is taken once, within its
  window, for the node and the values it signs.
* Live: someone who learnt the line's partition but not its key (:mod:`._sniffer`) forges and replays
  every grant, acknowledgement, announcement, command and tuning, and asks for a retune, a slower
  clock and an abort through the parameter services and the abort service. The line ends as a clean
  run does: every message but ``/diagnostics`` (which counts what was refused) byte for byte the clean
  run's, and every request refused with the reason.
"""

from __future__ import annotations

import secrets
import time
from pathlib import Path
from typing import TYPE_CHECKING

import pytest
from _ros_env import sniffer_environment
from sensor_msgs.msg import TimeReference
from std_msgs.msg import String

from folder_line.interfaces import COMMANDS_TOPIC, DIAGNOSTICS_TOPIC, NS_PER_S, PARTICIPANTS_TOPIC
from folder_line.ros.lockstep import PARTICIPANTS_QOS
from folder_line.ros.lockstep_messages import Announcement, format_announcement
from folder_line.ros.recorder import LineRecorder
from folder_line.ros.signing import REQUEST_WINDOW, RequestGuard, Signer, line_signer, sign_request, without_signature
from folder_line.ros.topics import COMMANDS_QOS

from ._line_runs import run_under_attack
from ._signed import time_reference
from .test_strangers import DURATION, line_records
from .test_strangers import clean as clean

if TYPE_CHECKING:
    from .conftest import Ros

KEY = bytes(range(16))


def test_a_signed_text_opens_under_its_key_and_context_only() -> None:
    signer = Signer(KEY)
    signed = signer.sign('step=5000000', 'grant', 'line_clock', '1.0')
    assert signed.startswith('step=5000000 sig=') and len(signed) == len('step=5000000 sig=') + 32
    assert signer.open(signed, 'grant', 'line_clock', '1.0') == 'step=5000000'
    assert without_signature(signed) == 'step=5000000'
    for text, context in (
        (signed, ('grant', 'line_clock', '2.0')),  # another stamp
        (signed, ('progress', 'line_clock', '1.0')),  # another kind of message
        (signed.replace('step=5', 'step=6'), ('grant', 'line_clock', '1.0')),  # a changed text
    ):
        with pytest.raises(ValueError, match='signature does not match'):
            signer.open(text, *context)
    with pytest.raises(ValueError, match='signature does not match'):
        Signer(bytes(16)).open(signed, 'grant', 'line_clock', '1.0')  # another line's key
    with pytest.raises(ValueError, match='unsigned'):
        signer.open('step=5000000', 'grant', 'line_clock', '1.0')


def test_an_open_line_signs_and_checks_nothing() -> None:
    open_line = Signer(None)
    assert not open_line.keyed
    assert open_line.sign('stop', 'command') == 'stop'
    assert open_line.open('stop', 'command') == 'stop'
    assert RequestGuard('supervisor', open_line).check(None, [('rtf', 0.5)]) == ''


def test_this_process_signs_with_the_test_process_key() -> None:
    assert line_signer().keyed  # test/_ros_env.py gives every test process a key


def test_a_request_is_taken_once_for_its_node_and_values_within_its_window() -> None:
    signer = Signer(KEY)
    values = [('V_tr', 6.0)]
    signature = sign_request('feed_transporter', values, signer)
    assert RequestGuard('belt_conveyor', signer).check(signature, values).endswith('with the line key')
    guard = RequestGuard('feed_transporter', signer)
    assert guard.check(signature, [('V_tr', 6.5)]).endswith('with the line key')  # other values
    assert guard.check(sign_request('feed_transporter', values, Signer(bytes(16))), values).endswith('line key')
    assert guard.check(signature, values) == ''
    assert 'already taken' in guard.check(signature, values)  # played again
    assert 'must be signed' in guard.check(None, values)
    assert 'not <wall ns>' in guard.check('abc', values)
    old = f'{time.time_ns() - round(2 * REQUEST_WINDOW * 1e9)}.{secrets.token_hex(8)}'
    text = 'V_tr=6.0\n@feed_transporter'  # what sign_request signs after the time and nonce
    stale = f'{old}.{signer.digest(old, text)}'
    assert guard.check(stale, values).startswith('line_signature: signed 60 s ago')


# rclpy warns when a service's answer cannot be sent in time (the sniffer reads its answers late, or its
# client is not matched yet): the node goes on, as rclcpp's would; pytest would make the warning an error
@pytest.mark.filterwarnings(r'ignore:failed to send response \(timeout\):RuntimeWarning')
def test_without_the_key_the_partition_alone_steers_and_forges_nothing(clean: Path, tmp_path: Path) -> None:
    result, attack = run_under_attack('_sniffer.py', sniffer_environment(), tmp_path, DURATION)
    out = tmp_path / 'attacked'
    assert attack['published'] >= 10 * attack['topics'] > 0  # ten rounds or more, while the line ran
    assert attack['replayed'] > 100  # it heard the line's signed messages, and played them again
    answers: dict[str, list[tuple[bool, str]]] = {}
    for what, ok, why in attack['answers']:
        answers.setdefault(what, []).append((ok, why))
    assert set(answers) == {'V_tr unsigned', 'V_tr made-up', 'rtf unsigned', 'operator_command made-up', 'abort'}
    for what, got in answers.items():
        assert got and not any(ok for ok, _ in got), (what, got)  # every request refused
    assert all('must be signed' in why for _, why in answers['V_tr unsigned'] + answers['rtf unsigned'])
    assert all('does not sign this change' in why for _, why in answers['V_tr made-up'])
    assert all('does not sign this change' in why for _, why in answers['operator_command made-up'])
    assert all('must first be signed' in why for _, why in answers['abort'])

    assert result.summary.outcome.ok, result.summary.outcome
    bag = result.summary.bag
    assert bag is not None and bag.lost == dict.fromkeys(bag.lost or {}, 0)
    attacked, _ = line_records(out)
    reference, _ = line_records(clean)
    assert {r: n for r, n in attacked.items() if r[0] != DIAGNOSTICS_TOPIC} == {
        r: n for r, n in reference.items() if r[0] != DIAGNOSTICS_TOPIC
    }
    assert not any('V_tr' in str(r[3]) for r in attacked)  # no retune reached the record


def test_the_recorder_takes_each_signed_command_and_announcement_once(ros: Ros) -> None:
    """A copy of a command or announcement (played again by someone who heard it) is refused, as is an
    unsigned one: the supervisor publishes each command once, line_clock announces once."""
    recorder = ros.add(LineRecorder(context=ros.context))
    sender = ros.node('sender')
    commands = sender.create_publisher(TimeReference, COMMANDS_TOPIC, COMMANDS_QOS)
    announce = sender.create_publisher(String, PARTICIPANTS_TOPIC, PARTICIPANTS_QOS)
    assert ros.spin_until(
        lambda: commands.get_subscription_count() >= 1 and announce.get_subscription_count() >= 1, timeout=20.0
    )
    hold = time_reference('supervisor', NS_PER_S, 'hold', 'command', NS_PER_S + 5)
    text = format_announcement(Announcement('lockstep', None, ('crank_drive', 'line_recorder')))
    for msg in (hold, hold, time_reference('supervisor', NS_PER_S, 'stop', 'progress')):  # twice, then unsigned
        commands.publish(msg)
    for data in (text, text):
        announce.publish(String(data=data))
    assert ros.spin_until(lambda: recorder.refused == {COMMANDS_TOPIC: 2, PARTICIPANTS_TOPIC: 1}, timeout=20.0), (
        recorder.refused
    )
    ros.spin_for(0.3)
    assert recorder.refused == {COMMANDS_TOPIC: 2, PARTICIPANTS_TOPIC: 1}  # the first of each taken
