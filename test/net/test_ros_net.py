"""Two rclpy processes on two hosts talk over UDP through the switch, and only through it.

Namespaces share ``/dev/shm``: Fast DDS's shared-memory transport would carry the
messages past the switch. ``FASTDDS_BUILTIN_TRANSPORTS=UDPv4`` leaves only UDP; the proof
is the cut: while the talker's link is down, nothing arrives, and after it is up again
messages flow again. (Measured: with Fast DDS's default transports the processes map
its shared-memory segments but still talk over UDP here, as each namespace's host looks
like another machine to it; UDPv4 only is set all the same, and checked.)
"""

from __future__ import annotations

import subprocess
from pathlib import Path

from .netns import Host, Network
from .probes import PYTHON, Lines, domain_id, ros_environment

TOPIC = 'net_check'

TALKER = f"""
import rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node('net_talker')
pub = node.create_publisher(String, {TOPIC!r}, 10)
count = 0
def tick():
    global count
    pub.publish(String(data=str(count)))
    print('pub', count, flush=True)
    count += 1
node.create_timer(0.02, tick)
rclpy.spin(node)
"""

LISTENER = f"""
import rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node('net_listener')
node.create_subscription(String, {TOPIC!r}, lambda msg: print('got', msg.data, flush=True), 10)
print('ready', flush=True)
rclpy.spin(node)
"""


def _start(host: Host, script: str, env: dict[str, str], log: Path) -> Lines:
    with open(log, 'wb') as err:
        proc = host.popen([PYTHON, '-c', script], env=env, stdout=subprocess.PIPE, stderr=err, text=True)
    return Lines(proc)


def _logs(workdir: Path) -> str:
    return '\n'.join(f'{name}: {(workdir / f"{name}.log").read_text()}' for name in ('talker', 'listener'))


def _numbers(lines: list[str], word: str) -> list[int]:
    return [int(line.split()[1]) for line in lines if line.startswith(f'{word} ')]


def test_ros_messages_cross_the_switch_and_stop_while_the_link_is_cut(net: Network, tmp_path: Path) -> None:
    env = ros_environment(tmp_path, domain_id())
    talker = _start(net['a'], TALKER, env, tmp_path / 'talker.log')
    listener = _start(net['b'], LISTENER, env, tmp_path / 'listener.log')
    assert listener.wait_for(lambda lines: len(_numbers(lines, 'got')) >= 10, timeout=60.0), _logs(tmp_path)
    # UDPv4 only: no shared-memory segment of Fast DDS (the default maps /dev/shm/fastdds_*)
    maps = Path(f'/proc/{talker.proc.pid}/maps').read_text()
    assert '/dev/shm/fastdds' not in maps

    net.cut('a')
    [published_at_cut] = _numbers(talker.lines, 'pub')[-1:]
    heard_at_cut = len(_numbers(listener.lines, 'got'))
    before = net.counters()['a']
    # 1 s of publishing (50 messages) into the cut
    assert talker.wait_for(lambda lines: _numbers(lines, 'pub')[-1] >= published_at_cut + 50, timeout=30.0), _logs(
        tmp_path
    )
    dropped = net.counters()['a'] - before
    during = _numbers(listener.lines, 'got')[heard_at_cut:]
    # at most the one published as the cut began (its line not yet read) came through
    assert all(n <= published_at_cut + 1 for n in during), during
    assert dropped.cut > 0 and dropped.tx == 0, dropped  # the talker kept sending: the switch dropped it

    net.cut('a', False)
    [published_at_heal] = _numbers(talker.lines, 'pub')[-1:]
    healed = listener.wait_for(lambda lines: max(_numbers(lines, 'got')) > published_at_heal + 10, timeout=30.0)
    assert healed, _logs(tmp_path)
    print(
        f'\ncut at #{published_at_cut}: {len(during)} heard during the cut, {dropped.cut} frames cut; '
        f'healed at #{published_at_heal}, heard up to #{max(_numbers(listener.lines, "got"))}'
    )
