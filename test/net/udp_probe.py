"""UDP probes run inside the test hosts' namespaces (standard library only; a script, not a test).

``recv --port P [--group G]``
    Prints ``ready`` once bound (and joined to multicast group ``G``), then one line per
    datagram: ``rx SEQ SIZE OK DELAY_NS``, ``OK`` 1 if its payload is intact and
    ``DELAY_NS`` its one-way delay (send and receive stamps are both CLOCK_MONOTONIC, one
    clock for every namespace of the machine). Ends at the end of its stdin.
``send --to ADDR:PORT --count N [--start S] [--size B] [--rate HZ]``
    Sends datagrams ``S .. S+N-1`` of ``B`` bytes, at most ``HZ`` per second (0: no
    pacing), then prints ``sent N``.

A datagram is a header (sequence number, send time, size) and a payload that is a
function of its sequence number, so that a corrupted or misassembled datagram is seen.
"""

from __future__ import annotations

import argparse
import selectors
import socket
import struct
import sys
import time

HEADER = struct.Struct('!qqI')  # seq, monotonic send time (ns), size
RCVBUF = 16 << 20
_PATTERN = bytes(range(251)) * 300  # 75 300 bytes: any payload up to 65 000 at any offset < 251


def payload(seq: int, size: int) -> bytes:
    """Datagram ``seq`` of ``size`` bytes (at least the header), stamped now."""
    body = size - HEADER.size
    start = seq % 251
    return HEADER.pack(seq, time.monotonic_ns(), size) + _PATTERN[start : start + body]


def check(data: bytes) -> tuple[int, bool, int]:
    """``(seq, intact, one-way delay ns)`` of a datagram received now."""
    now = time.monotonic_ns()
    if len(data) < HEADER.size:
        return -1, False, 0
    seq, sent, size = HEADER.unpack_from(data)
    start = seq % 251
    intact = size == len(data) and data[HEADER.size :] == _PATTERN[start : start + size - HEADER.size]
    return seq, intact, now - sent


def receive(port: int, group: str | None) -> None:
    """Print every datagram that arrives on ``port`` until stdin ends."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:  # root in the namespace: beyond rmem_max, so that a burst is not dropped here
        sock.setsockopt(socket.SOL_SOCKET, 33, RCVBUF)  # SO_RCVBUFFORCE
    except OSError:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RCVBUF)
    sock.bind(('', port))
    if group:
        mreq = struct.pack('4s4s', socket.inet_aton(group), socket.inet_aton('0.0.0.0'))
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, mreq)
    sock.setblocking(False)
    sel = selectors.DefaultSelector()
    sel.register(sock, selectors.EVENT_READ)
    sel.register(sys.stdin, selectors.EVENT_READ)
    print('ready', flush=True)
    while True:
        for key, _ in sel.select():
            if key.fileobj is not sock:  # stdin
                if not sys.stdin.readline():
                    return
                continue
            while True:
                try:
                    data = sock.recv(70000)
                except BlockingIOError:
                    break
                seq, intact, delay = check(data)
                print(f'rx {seq} {len(data)} {int(intact)} {delay}')
            sys.stdout.flush()


def send(to: str, count: int, start: int, size: int, rate: float) -> None:
    """Send ``count`` datagrams to ``to`` (``ADDR:PORT``), paced at ``rate`` per second."""
    addr, port = to.rsplit(':', 1)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)
    t0 = time.monotonic()
    for i in range(count):
        if rate > 0.0 and (ahead := t0 + i / rate - time.monotonic()) > 0.0:
            time.sleep(ahead)
        sock.sendto(payload(start + i, size), (addr, int(port)))
    print(f'sent {count}', flush=True)


def main() -> None:
    """The command line (see the module's doc)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest='mode', required=True)
    r = sub.add_parser('recv')
    r.add_argument('--port', type=int, required=True)
    r.add_argument('--group')
    s = sub.add_parser('send')
    s.add_argument('--to', required=True)
    s.add_argument('--count', type=int, default=1)
    s.add_argument('--start', type=int, default=0)
    s.add_argument('--size', type=int, default=64)
    s.add_argument('--rate', type=float, default=0.0)
    a = parser.parse_args()
    if a.mode == 'recv':
        receive(a.port, a.group)
    else:
        send(a.to, a.count, a.start, max(a.size, HEADER.size), a.rate)


if __name__ == '__main__':
    main()
