"""The line's Fast DDS profile (``folder_line/ros/fastdds_line.xml``): who loads it, what it holds, what it does.

* :func:`use_line_profile` points ``FASTDDS_DEFAULT_PROFILES_FILE`` at it unless the user
  named a file of their own or the RMW is not Fast DDS;
* the file holds the values :mod:`folder_line.ros.dds_profile` reads back, and Fast DDS parses
  it without an error (a broken copy shows that the check sees one);
* with real processes over rmw_fastrtps_cpp: a SIGKILLed participant leaves another's graph
  after about the lease, not before 0.6 of it; and, over UDP on this host, a sample lost
  on the wire is repaired one heartbeat period later, a writer with everything acknowledged
  sends no heartbeat, and a 5 s cut of the link is waited out (nobody leaves the graph,
  every sample published into the cut arrives after it).

The loss and the cut are made by a tiny ``LD_PRELOAD`` library (C, built here with ``cc``;
the test is skipped without one) that drops the process's own outgoing RTPS datagrams:
the first one holding a marker, and all of them while a file exists. Shared memory would
bypass it: those processes use UDPv4 only (``FASTDDS_BUILTIN_TRANSPORTS``, discovery range
``SUBNET``, as rmw_fastrtps's ``LOCALHOST`` range adds its own shared-memory transport),
kept to 127.0.0.1 by locators added to a copy of the line's profile.
"""

from __future__ import annotations

import ctypes.util
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

from folder_line.errors import ParameterError
from folder_line.ros.dds_profile import (
    GRAPH_TOPIC,
    HEARTBEAT_PERIOD,
    LEASE_ANNOUNCEMENT,
    LEASE_DURATION,
    PROFILE,
    PROFILE_FILE,
    PROFILES_FILE_VARIABLE,
    line_partition,
    line_profile_text,
    read_profile,
    use_line_profile,
)
from folder_line.ros.line_key import KEY_BYTES, KEY_VARIABLE, ensure_key, partition_name, read_key

if TYPE_CHECKING:
    from .conftest import Ros

NS = 'http://www.eprosima.com'
LEGACY_VARIABLE = 'FASTRTPS_DEFAULT_PROFILES_FILE'
XSD = Path(sys.prefix) / 'share' / 'fastdds' / 'fastdds_profiles.xsd'  # shipped with the Fast DDS wheel
CUT = 5.0  # s: a network cut the lease must wait out


# --- the environment -----------------------------------------------------------------------------------


def test_sets_the_variable_to_the_shipped_file() -> None:
    env: dict[str, str] = {'ROS_DOMAIN_ID': '3'}
    assert use_line_profile(env) == str(PROFILE_FILE)
    assert env == {'ROS_DOMAIN_ID': '3', PROFILES_FILE_VARIABLE: str(PROFILE_FILE)}
    assert Path(env[PROFILES_FILE_VARIABLE]).is_absolute() and PROFILE_FILE.is_file()


@pytest.mark.parametrize('rmw', ['rmw_fastrtps_cpp', 'rmw_fastrtps_dynamic_cpp', ''])
def test_applies_to_every_fast_dds_rmw_and_the_default(rmw: str) -> None:
    env = {'RMW_IMPLEMENTATION': rmw}
    assert use_line_profile(env) == str(PROFILE_FILE) == env[PROFILES_FILE_VARIABLE]


@pytest.mark.parametrize('variable', [PROFILES_FILE_VARIABLE, LEGACY_VARIABLE])
def test_the_users_own_file_is_kept(variable: str) -> None:
    env = {variable: '/etc/my_profiles.xml'}
    assert use_line_profile(env) == '/etc/my_profiles.xml'
    assert env == {variable: '/etc/my_profiles.xml'}


def test_an_empty_variable_is_no_file() -> None:
    env = {PROFILES_FILE_VARIABLE: ''}
    assert use_line_profile(env) == str(PROFILE_FILE) == env[PROFILES_FILE_VARIABLE]


def test_another_rmw_is_left_alone() -> None:
    env = {'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp'}
    assert use_line_profile(env) is None
    assert env == {'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp'}


def test_the_default_is_this_process_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    for variable in (PROFILES_FILE_VARIABLE, LEGACY_VARIABLE, 'RMW_IMPLEMENTATION', KEY_VARIABLE):
        monkeypatch.setenv(variable, 'x')  # recorded, so that the test's own setting is undone too
        monkeypatch.delenv(variable)
    assert use_line_profile() == str(PROFILE_FILE) == os.environ[PROFILES_FILE_VARIABLE]


# --- the line's key: its partition ---------------------------------------------------------------------

KEY = '00112233445566778899aabbccddeeff'


def _partitions(path: Path) -> dict[str, str]:
    """profile name -> the value of its ``partitions`` property."""
    out = {}
    for profile in ET.parse(path).getroot().iter():
        for prop in profile.findall(f'{{{NS}}}propertiesPolicy/{{{NS}}}properties/{{{NS}}}property'):
            if prop.findtext(f'{{{NS}}}name') == 'partitions':
                out[profile.get('profile_name', '')] = prop.findtext(f'{{{NS}}}value', '')
    return out


def test_a_key_puts_the_readers_in_its_partition_and_the_writers_in_it_and_the_default(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv('XDG_RUNTIME_DIR', str(tmp_path))
    env = {KEY_VARIABLE: KEY}
    path = Path(str(use_line_profile(env)))
    partition = partition_name(bytes.fromhex(KEY))
    assert env == {KEY_VARIABLE: KEY, PROFILES_FILE_VARIABLE: str(path)} and line_partition(env) == partition
    assert path.parent == tmp_path / f'folder_line-{os.getuid()}' and path.parent.stat().st_mode & 0o777 == 0o700
    assert re.fullmatch(r'folder_line_[0-9a-f]{16}', partition) and KEY not in path.read_text()  # not the key
    assert _partitions(path) == {
        'folder_line_writer': f';{partition}',  # the default partition ('') and the line's
        'folder_line_reader': partition,
        GRAPH_TOPIC: f';{partition}',  # the graph's names of nodes outside the line
    }
    assert read_profile(path) == PROFILE  # the rest of the line's profile, unchanged
    # another key, another partition; the same key, the same file (rewritten only if it differs)
    assert partition_name(bytes.fromhex(KEY[::-1])) != partition
    path.write_text('stale')
    assert use_line_profile({KEY_VARIABLE: KEY}) == str(path) and _partitions(path)[GRAPH_TOPIC] == f';{partition}'


def test_without_a_key_or_with_the_users_own_file_the_line_is_open() -> None:
    assert line_partition({}) is None
    env = {KEY_VARIABLE: KEY, PROFILES_FILE_VARIABLE: '/nowhere/my_profiles.xml'}
    assert use_line_profile(env) == '/nowhere/my_profiles.xml' and line_partition(env) is None


@pytest.mark.parametrize('text', ['xyz', '0011', 'g' * 32, '00112233445566778899aabbccddee'])
def test_a_key_that_is_not_one_is_refused_with_its_name(text: str) -> None:
    with pytest.raises(ParameterError) as refused:
        use_line_profile({KEY_VARIABLE: text})
    assert refused.value.key == KEY_VARIABLE and 'hex digits' in refused.value.reason
    assert read_key({KEY_VARIABLE: ' ' + KEY + ' '}) == bytes.fromhex(KEY) and read_key({KEY_VARIABLE: ''}) is None


def test_a_profiles_folder_that_is_not_private_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv('XDG_RUNTIME_DIR', str(tmp_path))
    (tmp_path / f'folder_line-{os.getuid()}').mkdir(mode=0o755)
    os.chmod(tmp_path / f'folder_line-{os.getuid()}', 0o755)  # others may write a profile for us to load
    with pytest.raises(OSError, match='not a private folder'):
        use_line_profile({KEY_VARIABLE: KEY})


def test_ensure_key_makes_one_once() -> None:
    env: dict[str, str] = {}
    key, made = ensure_key(env)
    assert made and len(key) == KEY_BYTES and env[KEY_VARIABLE] == key.hex()
    assert ensure_key(env) == (key, False)


# --- the file ------------------------------------------------------------------------------------------


def test_the_file_holds_what_the_module_reads() -> None:
    assert read_profile(PROFILE_FILE) == PROFILE
    assert PROFILE.heartbeat_period == HEARTBEAT_PERIOD
    assert (PROFILE.lease_duration, PROFILE.lease_announcement) == (LEASE_DURATION, LEASE_ANNOUNCEMENT)
    # a lost sample waits one period: tens of ms, not Fast DDS's 3 s; answers are not held back longer
    assert 0.005 <= HEARTBEAT_PERIOD <= 0.05
    assert PROFILE.nack_response_delay < HEARTBEAT_PERIOD and PROFILE.heartbeat_response_delay < HEARTBEAT_PERIOD
    # a cut of CUT s is waited out (the last announcement may be one period older), a killed node leaves well
    # before Fast DDS's 20 s; a participant announces itself several times per lease
    assert CUT + LEASE_ANNOUNCEMENT < LEASE_DURATION < 20.0
    assert LEASE_DURATION >= 5 * LEASE_ANNOUNCEMENT
    assert PROFILE.receive_buffer >= 2**21 and PROFILE.send_buffer >= 2**20


def test_the_file_leaves_the_transports_alone() -> None:
    """Built-in transports (shared memory on a host) stay, and FASTDDS_BUILTIN_TRANSPORTS still chooses.

    Fast DDS applies that variable only while ``useBuiltinTransports`` is true, and an XML
    ``builtinTransports`` sets it false when parsed; user transports would come on top.
    """
    root = ET.parse(PROFILE_FILE).getroot()
    assert root.tag == f'{{{NS}}}dds'
    tags = {element.tag.rpartition('}')[2] for element in root.iter()}
    assert not tags & {'useBuiltinTransports', 'builtinTransports', 'userTransports', 'transport_descriptors'}
    assert not tags & {'domainId', 'initialPeersList', 'metatrafficUnicastLocatorList', 'defaultUnicastLocatorList'}
    profiles = root.findall(f'{{{NS}}}profiles/*')
    assert sorted(p.tag.rpartition('}')[2] for p in profiles) == ['data_reader', 'data_writer', 'participant']
    assert all(p.get('is_default_profile') == 'true' for p in profiles)


@pytest.mark.skipif(not XSD.is_file(), reason='no Fast DDS XML schema in this environment')
def test_every_element_is_one_of_the_fast_dds_schema() -> None:
    schema = XSD.read_text(encoding='utf-8')
    keyed = ET.fromstring(line_profile_text('folder_line_0123456789abcdef'))
    for element in [*ET.parse(PROFILE_FILE).getroot().iter(), *keyed.iter()]:
        if not isinstance(element.tag, str):
            continue  # a comment
        tag = element.tag.rpartition('}')[2]
        assert f'name="{tag}"' in schema, tag


# --- real processes ------------------------------------------------------------------------------------


def _line_env(node_env: dict[str, str], profile: Path | None = None) -> dict[str, str]:
    """``node_env`` (this test process's ROS domain) with the line's profile, or ``profile``."""
    env = {k: v for k, v in node_env.items() if k not in (PROFILES_FILE_VARIABLE, LEGACY_VARIABLE)}
    if use_line_profile(env) is None:
        pytest.skip(f'RMW_IMPLEMENTATION={env["RMW_IMPLEMENTATION"]} is not Fast DDS')
    if profile is not None:
        env[PROFILES_FILE_VARIABLE] = str(profile)
    return env


class Child:
    """A Python process whose output lines (stdout and stderr) are collected as they come."""

    def __init__(self, script: str, args: list[str], env: dict[str, str]) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, '-c', script, *args],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        self.lines: list[str] = []
        self._changed = threading.Condition()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            with self._changed:
                self.lines.append(line.rstrip('\n'))
                self._changed.notify_all()

    def wait_for(self, predicate: Callable[[list[str]], bool], timeout: float) -> bool:
        with self._changed:
            return self._changed.wait_for(lambda: predicate(self.lines) or self.proc.poll() is not None, timeout) and (
                predicate(self.lines)
            )

    def words(self, first: str) -> list[list[str]]:
        with self._changed:
            return [line.split()[1:] for line in self.lines if line.startswith(first + ' ')]

    def stop(self, sig: signal.Signals = signal.SIGKILL) -> str:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self._reader.join(timeout=5)
        return '\n'.join(self.lines)


@pytest.fixture
def children() -> Iterator[list[Child]]:
    started: list[Child] = []
    yield started
    for child in started:
        child.stop()


NODE = """
import sys, time, rclpy
from std_msgs.msg import Empty
rclpy.init()
node = rclpy.create_node(sys.argv[1])
node.create_publisher(Empty, sys.argv[2], 1)
print('ready', flush=True)
if sys.argv[3] == 'exit':
    time.sleep(1.0)  # Fast DDS logs from a thread of its own
    raise SystemExit
rclpy.spin(node)
"""


@pytest.mark.parametrize(
    ('broken', 'keyed'), [(False, True), (False, False), (True, False)], ids=['keyed', 'open', 'broken-copy']
)
def test_fast_dds_loads_the_file_without_an_error(
    node_env: dict[str, str], tmp_path: Path, children: list[Child], broken: bool, keyed: bool
) -> None:
    profile = None
    if not keyed:
        node_env = {k: v for k, v in node_env.items() if k != KEY_VARIABLE}
    if broken:  # the control: an element Fast DDS does not know
        profile = tmp_path / 'broken.xml'
        profile.write_text(PROFILE_FILE.read_text().replace('heartbeat_period>', 'heartbeat_periodx>'))
    child = Child(NODE, ['dds_profile_load', f'/dds_profile_load_{os.getpid()}', 'exit'], _line_env(node_env, profile))
    children.append(child)
    assert child.proc.wait(timeout=60) == 0, child.stop()
    output = child.stop()
    assert 'ready' in output
    assert ('XMLPARSER' in output) is broken, output


def test_a_killed_participant_leaves_the_graph_after_the_lease_not_before(
    ros: Ros, node_env: dict[str, str], children: list[Child]
) -> None:
    """The lease is the dead participant's own (it announces it): the observer's profile does not matter."""
    topic = f'/dds_profile_lease_{os.getpid()}'
    child = Child(NODE, ['dds_profile_victim', topic, 'spin'], _line_env(node_env))
    children.append(child)
    observer = ros.node('dds_profile_observer')
    assert ros.spin_until(lambda: observer.count_publishers(topic) == 1, 30.0), child.stop()
    ros.spin_for(LEASE_ANNOUNCEMENT)  # announced by now at its own period, not only at start-up
    child.proc.kill()
    killed = time.monotonic()
    child.proc.wait()
    gone = ros.spin_until(lambda: observer.count_publishers(topic) == 0, LEASE_DURATION + 15.0)
    after = time.monotonic() - killed
    names = observer.get_node_names()
    output = child.stop()
    print(f'\nkilled participant left the graph after {after:.2f} s (lease {LEASE_DURATION:g} s)')
    assert gone, f'still in the graph {after:.1f} s after SIGKILL'
    assert 'dds_profile_victim' not in names
    # not before: a cut or a stall this much shorter than the lease is waited out
    assert after > 0.6 * LEASE_DURATION
    assert after < LEASE_DURATION + LEASE_ANNOUNCEMENT + 2.0
    assert 'XMLPARSER' not in output, output


# --- over UDP, with loss and a cut -----------------------------------------------------------------------

SHIM = r"""
#define _GNU_SOURCE
#include <dlfcn.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <time.h>

static ssize_t (*real_sendmsg)(int, const struct msghdr *, int);
static ssize_t (*real_sendto)(int, const void *, size_t, int, const struct sockaddr *, socklen_t);
static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;
static const char *marker, *cut_file;
static long marker_left, sent, cut, heartbeats;
static double marker_dropped_at = -1;

__attribute__((constructor)) static void init(void) {
    real_sendmsg = (ssize_t (*)(int, const struct msghdr *, int))dlsym(RTLD_NEXT, "sendmsg");
    real_sendto = (ssize_t (*)(int, const void *, size_t, int, const struct sockaddr *, socklen_t))
        dlsym(RTLD_NEXT, "sendto");
    marker = getenv("LOSSY_MARKER");
    marker_left = marker && *marker ? 1 : 0;
    cut_file = getenv("LOSSY_CUT_FILE");
}

/* HEARTBEAT submessages (id 0x07) of user (not built-in) writers in an RTPS datagram */
static long user_heartbeats(const unsigned char *p, size_t n) {
    long count = 0;
    for (size_t off = 20; off + 4 <= n;) {
        unsigned lo = p[off + 2], hi = p[off + 3], len = (p[off + 1] & 1) ? (lo | hi << 8) : (lo << 8 | hi);
        if (p[off] == 0x07 && off + 12 <= n && (p[off + 11] & 0xC0) != 0xC0) count++;
        if (len == 0) break;
        off += 4 + len;
    }
    return count;
}

/* 1: drop this datagram */
static int drop(const unsigned char *p, size_t n) {
    struct stat st;
    int verdict = 0;
    if (n < 20 || memcmp(p, "RTPS", 4) != 0) return 0;
    pthread_mutex_lock(&lock);
    if (marker_left && memmem(p, n, marker, strlen(marker))) {
        struct timespec t;
        clock_gettime(CLOCK_MONOTONIC, &t);
        marker_dropped_at = t.tv_sec + t.tv_nsec * 1e-9;
        marker_left = 0;
        verdict = 1;
    } else if (cut_file && stat(cut_file, &st) == 0) {
        cut++;
        verdict = 1;
    } else {
        sent++;
        heartbeats += user_heartbeats(p, n);
    }
    pthread_mutex_unlock(&lock);
    return verdict;
}

ssize_t sendmsg(int fd, const struct msghdr *msg, int flags) {
    unsigned char buf[65536];
    size_t n = 0, total = 0;
    for (size_t i = 0; i < msg->msg_iovlen; i++) {
        size_t c = msg->msg_iov[i].iov_len;
        total += c;
        if (c > sizeof buf - n) c = sizeof buf - n;
        memcpy(buf + n, msg->msg_iov[i].iov_base, c);
        n += c;
    }
    return drop(buf, n) ? (ssize_t)total : real_sendmsg(fd, msg, flags);
}

ssize_t sendto(int fd, const void *b, size_t n, int flags, const struct sockaddr *a, socklen_t al) {
    return drop(b, n) ? (ssize_t)n : real_sendto(fd, b, n, flags, a, al);
}

int lossy_stats(char *out, int len) {
    pthread_mutex_lock(&lock);
    int r = snprintf(out, len, "%ld %ld %ld %.6f", sent, cut, heartbeats, marker_dropped_at);
    pthread_mutex_unlock(&lock);
    return r;
}
"""

MARKER = 'LOSE-ME'

WRITER = f"""
import ctypes, os, signal, sys, time, rclpy
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node('dds_profile_writer')
qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                 history=HistoryPolicy.KEEP_LAST)  # as the line's LINE_QOS
pub = node.create_publisher(String, sys.argv[1], qos)
shim = ctypes.CDLL(None)
def stats(word):
    buf = ctypes.create_string_buffer(200)
    shim.lossy_stats(buf, 200)
    print(word, buf.value.decode(), time.monotonic(), flush=True)
def spin(seconds):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.01)
signal.signal(signal.SIGTERM, lambda *_: (stats('stats'), os._exit(0)))
while pub.get_subscription_count() == 0:
    rclpy.spin_once(node, timeout_sec=0.05)
for i in range(3):
    pub.publish(String(data=f'warmup {{i}}'))
    spin(0.05)
spin(0.3)
stats('quiet')  # everything acknowledged
spin(0.5)
stats('quiet')
print('sent', {MARKER!r}, time.monotonic(), flush=True)
pub.publish(String(data={MARKER!r}))
n = 0
while True:
    spin(0.05)
    print('sent', n, time.monotonic(), flush=True)
    pub.publish(String(data=str(n)))
    n += 1
"""

READER = """
import sys, time, rclpy
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node('dds_profile_reader')
qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                 history=HistoryPolicy.KEEP_LAST)
topic = sys.argv[1]
node.create_subscription(String, topic, lambda msg: print('got', msg.data, time.monotonic(), flush=True), qos)
node.create_timer(0.1, lambda: print('publishers', node.count_publishers(topic), time.monotonic(), flush=True))
rclpy.spin(node)
"""


@pytest.fixture(scope='module')
def shim(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The ``LD_PRELOAD`` library that drops this process's outgoing RTPS datagrams (see :data:`SHIM`)."""
    cc = shutil.which('cc') or shutil.which('gcc')
    if cc is None or ctypes.util.find_library('c') is None:
        pytest.skip('no C compiler for the packet-dropping library')
    directory = tmp_path_factory.mktemp('shim')
    (directory / 'lossy.c').write_text(SHIM)
    library = directory / 'liblossy.so'
    done = subprocess.run(
        [cc, '-O2', '-Wall', '-shared', '-fPIC', '-o', str(library), str(directory / 'lossy.c'), '-ldl', '-lpthread'],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    return library


def _udp_only_profile(path: Path) -> Path:
    """The line's profile plus discovery and data on 127.0.0.1 only (no multicast); written to ``path``."""
    ET.register_namespace('', NS)
    tree = ET.parse(PROFILE_FILE)
    rtps = tree.getroot().find(f'.//{{{NS}}}participant/{{{NS}}}rtps')
    assert rtps is not None
    builtin = rtps.find(f'{{{NS}}}builtin')
    assert builtin is not None
    for parent, tag in (
        (builtin, 'metatrafficUnicastLocatorList'),
        (builtin, 'initialPeersList'),
        (rtps, 'defaultUnicastLocatorList'),
    ):
        locator = ET.SubElement(
            ET.SubElement(ET.SubElement(parent, f'{{{NS}}}{tag}'), f'{{{NS}}}locator'), f'{{{NS}}}udpv4'
        )
        ET.SubElement(locator, f'{{{NS}}}address').text = '127.0.0.1'
    tree.write(path, xml_declaration=True, encoding='UTF-8')
    assert read_profile(path) == PROFILE
    return path


def test_over_udp_a_lost_sample_is_repaired_at_the_next_heartbeat_and_a_cut_is_waited_out(
    node_env: dict[str, str], tmp_path: Path, shim: Path, children: list[Child]
) -> None:
    topic = f'/dds_profile_udp_{os.getpid()}'
    cut_file = tmp_path / 'cut'
    env = _line_env(node_env, _udp_only_profile(tmp_path / 'udp_only.xml'))
    env.update(
        ROS_AUTOMATIC_DISCOVERY_RANGE='SUBNET',  # LOCALHOST: rmw_fastrtps adds a shared-memory transport
        FASTDDS_BUILTIN_TRANSPORTS='UDPv4',
        LD_PRELOAD=str(shim),
        LOSSY_CUT_FILE=str(cut_file),  # both directions are cut
    )
    reader = Child(READER, [topic], env)
    children.append(reader)
    writer = Child(WRITER, [topic], dict(env, LOSSY_MARKER=MARKER))
    children.append(writer)

    def got(lines: list[str], data: str) -> bool:
        return any(line.startswith(f'got {data} ') for line in lines)

    # the lost sample: dropped once on the way out, repaired after the writer's next heartbeat
    assert reader.wait_for(lambda lines: got(lines, MARKER), 60.0), writer.stop() + '\n' + reader.stop()
    [[_, sent_at]] = [w for w in writer.words('sent') if w[0] == MARKER]
    [[_, arrived_at]] = [w for w in reader.words('got') if w[0] == MARKER]
    [before, after] = [[float(x) for x in w] for w in writer.words('quiet')]
    delay = float(arrived_at) - float(sent_at)
    # (Fast DDS's own period, 3 s, would repair it 3 s later: the writer's heartbeat timer starts with the sample)
    assert 0.5 * HEARTBEAT_PERIOD < delay < HEARTBEAT_PERIOD + 0.5, delay
    assert before[2] == after[2], 'a writer with everything acknowledged sent heartbeats'
    assert before[1] == 0 and before[0] > 0  # nothing cut yet, and the datagrams went out over UDP
    assert '/dev/shm/fastdds_' not in Path(f'/proc/{writer.proc.pid}/maps').read_text()  # not shared memory

    # the cut: nothing arrives during it; nobody leaves the graph; all of it arrives after it
    cut_file.touch()
    cut_at = time.monotonic()
    time.sleep(CUT)
    cut_file.unlink()
    healed_at = time.monotonic()
    last_in_cut = max(int(n) for n, t in writer.words('sent') if n != MARKER and float(t) < healed_at)
    assert reader.wait_for(lambda lines: got(lines, str(last_in_cut + 5)), 30.0), reader.stop()
    writer.stop(signal.SIGTERM)
    reader.stop()
    received = {int(w[0]): float(w[1]) for w in reader.words('got') if w[0].isdigit()}
    published = {int(n): float(t) for n, t in writer.words('sent') if n != MARKER}
    into_cut = [n for n, t in published.items() if cut_at + 0.1 < t < healed_at - 0.1]
    assert len(into_cut) > CUT / 0.05 / 2, into_cut
    assert set(range(last_in_cut + 6)) <= set(received), sorted(set(range(last_in_cut + 6)) - set(received))
    assert all(received[n] > healed_at - 0.1 for n in into_cut)
    counts = [(int(n), float(t)) for n, t in reader.words('publishers')]
    during = [n for n, t in counts if cut_at < t < healed_at + 1.0]
    assert len(during) > CUT / 0.1 / 2 and min(during) == 1, during
    [[_, cut_datagrams, _, dropped_at, _]] = writer.words('stats')
    assert int(cut_datagrams) > 0 and float(dropped_at) > 0  # the cut and the lost sample were the library's
    print(
        f'\nrepair of the lost sample: {delay * 1e3:.1f} ms (heartbeat period {HEARTBEAT_PERIOD * 1e3:g} ms); '
        f'{len(into_cut)} published into the {CUT:g} s cut arrived {min(received[n] for n in into_cut) - healed_at:.3f}'
        f'..{max(received[n] for n in into_cut) - healed_at:.3f} s after it; {cut_datagrams} datagrams cut'
    )


def test_folder_line_profile_prints_the_keys_profile(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from folder_line.cli.main import main

    monkeypatch.setenv(KEY_VARIABLE, KEY)
    monkeypatch.setenv(PROFILES_FILE_VARIABLE, '/nowhere/else.xml')  # the shell's own is not the line's
    assert main(['profile']) == 0
    path = Path(capsys.readouterr().out.strip())
    assert path.is_file() and _partitions(path)['folder_line_reader'] == partition_name(bytes.fromhex(KEY))
    monkeypatch.delenv(KEY_VARIABLE)
    assert main(['profile']) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith(f'folder-line: error: {KEY_VARIABLE} is not set')
