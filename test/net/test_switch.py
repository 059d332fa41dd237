"""The network harness: hosts in namespaces, UDP through the user-space switch and its impairments.

Delays are measured one way (both ends stamp with the machine's one CLOCK_MONOTONIC):
never below what the switch was told (minus 0.5 ms), and typically not far above it: the
median within 10 ms (a bound about the switch, generous for a loaded machine, where a
descheduled receiver stretches a few samples; the mean is printed). Loss is checked against a 5 sigma
binomial bound and against the switch's own count of what it dropped.
"""

from __future__ import annotations

import itertools
import math
import os
import statistics
import subprocess
from pathlib import Path

import pytest

from .netns import _IP, PREFIX, SUBNET, Network, NetworkError, PortCounters, cleanup_leftovers
from .probes import Receiver, flush, send, wait_until

MS = 1e6  # ns
SLACK_MS = 0.5  # a frame may leave this much before its due time (clock reads), never more
LATE_MS = 10.0  # median one-way delay above the configured one that still passes (machine load)
MARKER = 10**6


def _delays_ms(rx: Receiver, first: int, end: int) -> list[float]:
    got = rx.datagrams(first, end)
    assert sorted(got) == list(range(first, end)), f'missing {sorted(set(range(first, end)) - set(got))}'
    assert all(d.intact for d in got.values())
    return [got[s].delay_ns / MS for s in range(first, end)]


def _warm_up(net: Network, rx: Receiver, sender: str = 'a') -> None:
    """ARP resolved, the receiver reachable: a few datagrams before any impairment."""
    send(net[sender], rx.host.address, 5, start=0)
    assert rx.wait_for_count(0, 5)


def _changes(net: Network, before: dict[str, PortCounters]) -> dict[str, PortCounters]:
    return {host: counters - before[host] for host, counters in net.counters().items()}


def _inversions(order: list[int]) -> int:
    return sum(1 for x, y in itertools.pairwise(order) if y < x)


def test_udp_crosses_the_switch_with_the_delay_of_each_link(net: Network) -> None:
    a, b = net['a'], net['b']
    rx = Receiver(b)
    before = net.counters()
    send(a, b.address, 20, rate=500.0)  # the first ones wait for ARP
    assert rx.wait_for_count(0, 20)
    change = _changes(net, before)
    assert change['a'].rx >= 20 and change['b'].tx >= 20, change
    assert change['c'].tx <= 1, change  # learned: c saw at most the ARP broadcast
    base = _delays_ms(rx, 5, 20)
    print(f'\nno impairment: one way {statistics.mean(base):.3f} ms mean, {max(base):.3f} max')

    # a link's delay counts on frames from its host and to it: a to b crosses both
    for start, (delay_a, delay_b) in enumerate([(20.0, 0.0), (0.0, 20.0), (15.0, 5.0)], start=1):
        net.set('a', delay_ms=delay_a)
        net.set('b', delay_ms=delay_b)
        first = 1000 * start
        send(a, b.address, 40, start=first, rate=200.0)
        assert rx.wait_for_count(first, first + 40)
        delays = _delays_ms(rx, first, first + 40)
        want = delay_a + delay_b
        print(
            f'delay a {delay_a:g} + b {delay_b:g} ms: one way min {min(delays):.3f}, '
            f'mean {statistics.mean(delays):.3f}, median {statistics.median(delays):.3f}, max {max(delays):.3f} ms'
        )
        assert min(delays) >= want - SLACK_MS
        assert statistics.median(delays) <= want + LATE_MS
    final = net.wait_idle()
    assert all(c.err == 0 and c.kdrop == 0 for c in final.values()), final


def test_jitter_spreads_the_delay_and_reorders_unless_fifo(net: Network) -> None:
    a, b = net['a'], net['b']
    rx = Receiver(b)
    _warm_up(net, rx)
    delay, jitter, n = 10.0, 5.0, 200
    for fifo, first in ((False, 1000), (True, 2000)):
        net.set('a', delay_ms=delay, jitter_ms=jitter, fifo=fifo)
        send(a, b.address, n, start=first, rate=500.0)  # 2 ms apart: jitter of +-5 ms reorders them
        flush(net, a, rx, MARKER + first)
        delays = _delays_ms(rx, first, first + n)
        order = [s for s in rx.arrival_order() if first <= s < first + n]
        mean, median, spread = statistics.mean(delays), statistics.median(delays), statistics.pstdev(delays)
        print(
            f'\ndelay {delay:g} +- {jitter:g} ms, fifo {fifo}: one way min {min(delays):.3f}, mean {mean:.3f}, '
            f'median {median:.3f}, max {max(delays):.3f}, sd {spread:.3f} ms; {_inversions(order)} inversions'
        )
        assert min(delays) >= delay - jitter - SLACK_MS
        assert spread > 2.0  # uniform +-5 ms: 2.9 ms (without jitter: ~0)
        if fifo:
            assert order == sorted(order)
            assert mean >= delay - 1.0 and median <= delay + LATE_MS  # waiting in line: mean ~11.1 ms
        else:
            assert _inversions(order) > 0
            assert mean >= delay - 1.0 and median <= delay + LATE_MS  # 1.0 ms: 5 standard errors


@pytest.mark.parametrize('lossy', ['a', 'b'], ids=['sender_link', 'receiver_link'])
def test_loss_is_binomial_and_counted(net: Network, lossy: str) -> None:
    a, b = net['a'], net['b']
    rx = Receiver(b)
    _warm_up(net, rx)
    p, n, first = 0.05, 4000, 1000
    net.set(lossy, loss=p)
    before = net.counters()
    send(a, b.address, n, start=first, rate=20000.0)
    flush(net, a, rx, MARKER)
    change = _changes(net, before)
    got = rx.datagrams(first, first + n)
    missing = n - len(got)
    sigma = math.sqrt(n * p * (1.0 - p))
    print(f'\nloss {p} at {lossy}: {missing} of {n} lost (expected {n * p:g} +- {sigma:.1f}); switch: {change}')
    assert abs(missing - n * p) <= 5.0 * sigma
    assert all(d.intact for d in got.values())
    assert missing <= change[lossy].lost <= missing + 2  # every one the switch's, and counted (+ARP)
    assert all(c.err == 0 and c.kdrop == 0 for c in change.values()), change


def test_cut_drops_everything_to_and_from_a_host_until_healed(net: Network) -> None:
    a, b, c = net['a'], net['b'], net['c']
    to_b, to_c, to_a = Receiver(b), Receiver(c), Receiver(a)
    _warm_up(net, to_b)
    _warm_up(net, to_c)
    _warm_up(net, to_a, sender='b')
    net.cut('b')
    before = net.counters()
    send(a, b.address, 100, start=1000, rate=5000.0)
    send(b, a.address, 50, start=1000, rate=5000.0)
    send(a, c.address, 100, start=1000, rate=5000.0)  # the others still talk
    assert to_c.wait_for_count(1000, 1100)
    assert wait_until(lambda: (net.counters()['b'] - before['b']).cut >= 150, timeout=5.0)
    net.cut('b', False)
    send(a, b.address, 100, start=2000, rate=5000.0)
    send(b, a.address, 50, start=2000, rate=5000.0)
    assert to_b.wait_for_count(2000, 2100) and to_a.wait_for_count(2000, 2050)
    # sent before those that arrived, on the same path: had any got through, it would be here
    assert not to_b.datagrams(1000, 1100) and not to_a.datagrams(1000, 1050)
    change = _changes(net, before)
    print(f'\ncut b: {change}')
    assert change['b'].tx >= 100 and change['b'].rx >= 100  # b's 50 cut and 50 after
    assert change['a'].cut == 0 and change['c'].cut == 0 and change['c'].tx >= 100


@pytest.mark.parametrize('jitter', [0.0, 2.0], ids=['in_order', 'fragments_reordered'])
def test_large_datagrams_fragment_and_arrive_intact(net: Network, jitter: float) -> None:
    a, b = net['a'], net['b']
    rx = Receiver(b)
    _warm_up(net, rx)
    net.set('a', delay_ms=3.0 if jitter else 0.0, jitter_ms=jitter)
    size, n, first = 60000, 20, 1000
    before = net.counters()
    send(a, b.address, n, start=first, size=size, rate=100.0)
    assert rx.wait_for_count(first, first + n)
    got = rx.datagrams(first, first + n)
    assert all(d.intact and d.size == size for d in got.values())
    fragments = math.ceil((size + 8) / 1480)  # IPv4 payload per fragment at MTU 1500
    change = _changes(net, before)
    print(f'\n{n} datagrams of {size} bytes, jitter {jitter:g} ms: {change["a"].rx} frames from a')
    assert change['a'].rx >= n * fragments


def test_multicast_reaches_every_other_host(net: Network) -> None:
    group = '239.255.42.99'
    a, b, c = net['a'], net['b'], net['c']
    to_b, to_c = Receiver(b, group=group), Receiver(c, group=group)
    before = net.counters()
    send(a, group, 20, rate=500.0)
    assert to_b.wait_for_count(0, 20) and to_c.wait_for_count(0, 20)
    change = _changes(net, before)
    assert change['b'].tx >= 20 and change['c'].tx >= 20  # flooded
    net.cut('c')
    send(a, group, 20, start=100, rate=500.0)
    assert to_b.wait_for_count(100, 120)
    net.cut('c', False)
    send(a, group, 20, start=200, rate=500.0)
    assert to_c.wait_for_count(200, 220)
    assert not to_c.datagrams(100, 120)


def test_hosts_have_no_route_out_of_their_network(net: Network) -> None:
    a = net['a']
    routes = a.run(['ip', '-4', 'route', 'show']).stdout.splitlines()
    assert sorted(r.split()[0] for r in routes) == [f'{SUBNET}.0/24', '224.0.0.0/4'], routes
    assert all(' dev eth0 ' in f'{r} ' for r in routes)
    links = a.run(['ip', '-o', 'link', 'show']).stdout.splitlines()
    assert [line.split(':')[1].strip().split('@')[0] for line in links] == ['lo', 'eth0']
    lookup = a.run(['ip', 'route', 'get', '198.51.100.1'])  # a route lookup: nothing is sent
    assert lookup.returncode != 0 and 'unreachable' in lookup.stderr.lower(), lookup


def test_the_switch_refuses_a_bad_setting(net: Network) -> None:
    with pytest.raises(NetworkError, match='bad option'):
        net.set('a', loss=1.5)
    with pytest.raises(NetworkError, match='bad option'):
        net.set('a', delay_ms=-1.0)
    net.set('a', loss=0.5)  # still answering


def _netns_list() -> set[str]:
    out = subprocess.run([_IP, 'netns', 'list'], capture_output=True, text=True, check=True).stdout
    return {line.split()[0] for line in out.splitlines() if line.strip()}


def _root_links() -> set[str]:
    out = subprocess.run([_IP, '-o', 'link', 'show'], capture_output=True, text=True, check=True).stdout
    return {line.split(':')[1].strip() for line in out.splitlines()}


def _pid_alive(pid: int) -> bool:
    return Path(f'/proc/{pid}').exists() and 'State:\tZ' not in Path(f'/proc/{pid}/status').read_text()


def _pids(netns: str) -> list[int]:
    out = subprocess.run([_IP, 'netns', 'pids', netns], capture_output=True, text=True).stdout
    return [int(p) for p in out.split()]


def _argv(pid: int) -> list[str]:
    try:
        return Path(f'/proc/{pid}/cmdline').read_bytes().decode().split('\0')[:-1]
    except OSError:
        return []


def test_close_removes_namespaces_links_and_processes_even_after_an_error(switch_binary: Path, tmp_path: Path) -> None:
    links = _root_links()
    net = Network(['a', 'b'], tmp_path, switch=switch_binary)
    with pytest.raises(RuntimeError, match='the test failed'), net:
        assert set(net.namespaces) <= _netns_list()
        sleeper = net['a'].popen(['sleep', '60'])
        net['b'].popen(['setsid', '--fork', 'sleep', '61'])  # leaves its process group: found by its namespace
        assert wait_until(lambda: ['sleep', '61'] in map(_argv, _pids(net['b'].netns)), 10.0)
        inside = {ns: _pids(ns) for ns in net.namespaces}
        assert len(inside[net.switch_netns]) == 1 and inside[net['a'].netns] == [sleeper.pid]
        raise RuntimeError('the test failed')
    assert not set(net.namespaces) & _netns_list()
    assert _root_links() == links  # no veth end was ever in the root namespace, none is now
    assert sleeper.poll() is not None
    assert not any(_pid_alive(pid) for pids in inside.values() for pid in pids), inside


def test_a_network_that_cannot_start_leaves_nothing(tmp_path: Path, switch_binary: Path) -> None:
    net = Network(['a'], tmp_path, switch=tmp_path / 'no-such-switch')
    with pytest.raises(NetworkError, match='did not start'), net:
        pass
    assert not set(net.namespaces) & _netns_list()


def test_leftovers_of_a_dead_process_are_removed(switch_binary: Path) -> None:
    gone = subprocess.Popen(['true'])
    gone.wait()
    leftover, ours = f'{PREFIX}{gone.pid}n0-a', f'{PREFIX}{os.getpid()}n999-a'
    for name in (leftover, ours):
        subprocess.run([_IP, 'netns', 'add', name], check=True)
    try:
        subprocess.run([_IP, '-n', leftover, 'link', 'add', 'eth0', 'type', 'veth', 'peer', 'name', 'x'], check=True)
        removed = cleanup_leftovers()
        assert leftover in removed and ours not in removed
        assert leftover not in _netns_list() and ours in _netns_list()
    finally:
        for name in (leftover, ours):
            subprocess.run([_IP, 'netns', 'del', name], capture_output=True)
