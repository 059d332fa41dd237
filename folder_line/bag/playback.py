"""What ``folder-line bag play`` plays, without ROS: the window, the topics, the QoS recorded, the raw messages.

:func:`play_plan` checks a bag (:func:`folder_line.bag.reader.read_bag`) and the
options against it, and :func:`raw_messages` yields the CDR bytes of the messages of
the window in log-time order, never deserialized: the player publishes them as they
were recorded, byte for byte. :func:`recorded_qos` reads a topic's
``offered_qos_profiles`` from ``metadata.yaml`` (rosbag2's keys and values, numbers or
names), empty when the bag recorded none -- the player then uses the QoS the line's
own publisher of that topic has (:mod:`folder_line.ros.player`).
:func:`wall_offset` is the pacing: the wall time at which a message is due.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass

from folder_line.bag.metadata import read_metadata
from folder_line.bag.reader import BagContents, read_bag
from folder_line.errors import ParameterError
from folder_line.interfaces import CLOCK_TOPIC, NS_PER_S

__all__ = ['PlayPlan', 'QosSpec', 'play_plan', 'raw_messages', 'recorded_qos', 'wall_offset']


@dataclass(frozen=True)
class QosSpec:
    """A QoS profile as rosbag2 records it (``offered_qos_profiles``), in words.

    Attributes
    ----------
    reliability : str
        ``reliable`` or ``best_effort``.
    durability : str
        ``transient_local`` or ``volatile``.
    history : str
        ``keep_last`` or ``keep_all``.
    depth : int
        History depth (``keep_last``), messages.
    """

    reliability: str
    durability: str
    history: str
    depth: int


#: rosbag2 writes a policy as its rmw enum number (humble .. jazzy) or as its name (later)
_POLICY_NAMES: dict[str, dict[int, str]] = {
    'reliability': {0: 'system_default', 1: 'reliable', 2: 'best_effort'},
    'durability': {0: 'system_default', 1: 'transient_local', 2: 'volatile'},
    'history': {0: 'system_default', 1: 'keep_last', 2: 'keep_all'},
}


def _policy(entry: Mapping[str, object], key: str, default: str) -> str:
    value = entry.get(key, default)
    if isinstance(value, int):
        return _POLICY_NAMES[key].get(value, default)
    text = str(value).strip().lower().replace(' ', '_')
    return text if text in _POLICY_NAMES[key].values() else default


def recorded_qos(contents: BagContents) -> dict[str, QosSpec]:
    """Topic -> the first QoS profile its publishers offered, as ``metadata.yaml`` records it.

    Topics with no recorded profile (``offered_qos_profiles: []``, what the line's bags
    hold) are left out; so are entries that are not mappings.
    """
    data = read_metadata(contents.path)
    info = data.get('rosbag2_bagfile_information', {}) if isinstance(data, dict) else {}
    found: dict[str, QosSpec] = {}
    for item in info.get('topics_with_message_count') or []:
        meta = item.get('topic_metadata', {}) if isinstance(item, dict) else {}
        profiles = meta.get('offered_qos_profiles') if isinstance(meta, dict) else None
        if isinstance(profiles, list) and profiles and isinstance(profiles[0], dict):
            p = profiles[0]
            depth = p.get('depth', 0)
            found[str(meta.get('name'))] = QosSpec(
                reliability=_policy(p, 'reliability', 'reliable'),
                durability=_policy(p, 'durability', 'volatile'),
                history=_policy(p, 'history', 'keep_last'),
                depth=depth if isinstance(depth, int) and depth > 0 else 1000,
            )
    return found


@dataclass(frozen=True)
class PlayPlan:
    """What one pass of ``bag play`` plays.

    Attributes
    ----------
    bag : BagContents
        The bag.
    topics : dict of str to str
        Topic -> message type, the topics played (``/clock`` always, if the bag has it).
    start_ns, end_ns : int
        Log-time window played, both ends included, ns of line time.
    """

    bag: BagContents
    topics: dict[str, str]
    start_ns: int
    end_ns: int

    @property
    def has_clock(self) -> bool:
        """Whether the bag's own ``/clock`` is played (else the player makes one at each message's time)."""
        return CLOCK_TOPIC in self.topics


def play_plan(path: str, start: float = 0.0, duration: float | None = None, topics: Sequence[str] = ()) -> PlayPlan:
    """Check the bag and the options; the window and topics to play.

    Parameters
    ----------
    path : str
        The bag directory.
    start : float, optional
        Where playing begins, s after the bag's first message (``--start``).
    duration : float, optional
        How much to play, s of line time (``--duration``; default: to the end).
    topics : sequence of str, optional
        Only these topics (``--topics``; default all). ``/clock`` is played in any case.

    Raises
    ------
    BagError
        The bag cannot be opened (:func:`folder_line.bag.reader.read_bag`).
    ParameterError
        A topic the bag does not have, or a ``--start`` at or past the bag's end.
    """
    bag = read_bag(path)
    for topic in topics:
        if topic not in bag.topics:
            raise ParameterError('--topics', topic, f'not a topic of the bag; it has {", ".join(bag.topics)}')
    chosen = {name: t.type for name, t in bag.topics.items() if not topics or name in topics or name == CLOCK_TOPIC}
    start_ns = bag.start_ns + round(start * NS_PER_S)
    if bag.message_count and start_ns > bag.end_ns:
        raise ParameterError('--start', start, f"past the bag's end ({bag.duration_ns / NS_PER_S:.9g} s long)")
    end_ns = bag.end_ns if duration is None else min(bag.end_ns, start_ns + round(duration * NS_PER_S))
    return PlayPlan(bag=bag, topics=chosen, start_ns=start_ns, end_ns=end_ns)


def raw_messages(plan: PlayPlan) -> Iterator[tuple[str, int, bytes]]:
    """``(topic, log time ns, CDR bytes)`` of the plan's window and topics, in log-time order.

    Raises
    ------
    BagError
        The bag cannot be opened.
    """
    for topic, _, t_ns, raw in plan.bag.raw_messages(list(plan.topics), plan.start_ns, plan.end_ns + 1):
        yield topic, t_ns, bytes(raw)


def wall_offset(t_ns: int, first_ns: int, rtf: float) -> float:
    """Wall time after the first message at which the message of log time ``t_ns`` is due, s (0 if ``rtf`` is 0).

    Parameters
    ----------
    t_ns, first_ns : int
        Log times of the message and of the first message played, ns.
    rtf : float
        Real-time factor (line seconds per wall second); 0: as fast as possible.
    """
    return 0.0 if rtf <= 0.0 else (t_ns - first_ns) / NS_PER_S / rtf
