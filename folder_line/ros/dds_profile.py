"""The Fast DDS profile of the line's processes: ``fastdds_line.xml``, shipped beside this module.

rmw_fastrtps loads the file named by ``FASTDDS_DEFAULT_PROFILES_FILE`` when a process makes
its first participant (``rclpy.init``); :func:`use_line_profile` sets that variable, so it
must run before. The file sets Fast DDS's *default* participant, DataWriter and DataReader
profiles, which rmw_fastrtps starts every entity from before it applies the ROS QoS
(reliability kind, durability, history, deadline, lifespan, liveliness): none of the
settings here is one of those, so they hold for every topic, service and participant:

* :data:`HEARTBEAT_PERIOD`: a reliable writer with unacknowledged samples sends a
  heartbeat this often (Fast DDS: 3 s), and the reader asks again for what it lacks; a
  lost sample that no later sample follows (the last one of a lockstep tick) is repaired
  within about this time. A writer with everything acknowledged sends none.
* :data:`LEASE_DURATION`: a participant not heard from for this long leaves the graph of
  the others (Fast DDS: 20 s); it announces itself every :data:`LEASE_ANNOUNCEMENT`. A
  killed process leaves within the lease; a network cut shorter than the lease minus one
  announcement period does not make it leave.
* the UDP socket buffers (the built-in transports; the kernel caps them at
  ``net.core.rmem_max`` / ``wmem_max``).

The numbers are read from the XML file (:func:`read_profile`), not repeated here.
"""

from __future__ import annotations

import contextlib
import copy
import math
import os
import stat
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Mapping, MutableMapping
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from folder_line.ros.line_key import partition_name, read_key

__all__ = [
    'GRAPH_TOPIC',
    'HEARTBEAT_PERIOD',
    'LEASE_ANNOUNCEMENT',
    'LEASE_DURATION',
    'PROFILE',
    'PROFILES_FILE_VARIABLE',
    'PROFILE_FILE',
    'DdsProfile',
    'line_partition',
    'line_profile_text',
    'read_profile',
    'use_line_profile',
]

PROFILE_FILE: Final = Path(__file__).with_name('fastdds_line.xml')
"""The line's Fast DDS XML profiles file (package data)."""

PROFILES_FILE_VARIABLE: Final = 'FASTDDS_DEFAULT_PROFILES_FILE'
"""The variable Fast DDS 3 reads the profiles file from."""

_USER_VARIABLES: Final = (PROFILES_FILE_VARIABLE, 'FASTRTPS_DEFAULT_PROFILES_FILE')  # the latter: Fast DDS 2's
_FASTDDS_RMWS: Final = frozenset({'rmw_fastrtps_cpp', 'rmw_fastrtps_dynamic_cpp'})
_NS: Final = {'dds': 'http://www.eprosima.com'}

GRAPH_TOPIC: Final = 'ros_discovery_info'
"""The topic on which each ROS participant tells the others its nodes (rmw_dds_common)."""


@dataclass(frozen=True)
class DdsProfile:
    """The settings of a profiles file: durations in seconds, buffer sizes in bytes.

    Attributes
    ----------
    heartbeat_period, nack_response_delay : float
        Of the default DataWriter (``<times>``).
    heartbeat_response_delay : float
        Of the default DataReader (``<times>``).
    lease_duration, lease_announcement : float
        Of the default participant (``<builtin><discovery_config>``).
    send_buffer, receive_buffer : int
        ``sendSocketBufferSize`` and ``listenSocketBufferSize`` of the default participant.
    """

    heartbeat_period: float
    nack_response_delay: float
    heartbeat_response_delay: float
    lease_duration: float
    lease_announcement: float
    send_buffer: int
    receive_buffer: int


def _default_profile(root: ET.Element, kind: str) -> ET.Element:
    for element in root.iterfind(f'dds:profiles/dds:{kind}', _NS):
        if element.get('is_default_profile') == 'true':
            return element
    raise ValueError(f'no default <{kind}> profile')


def _find(element: ET.Element, path: str) -> ET.Element:
    found = element.find('/'.join(f'dds:{tag}' for tag in path.split('/')), _NS)
    if found is None:
        raise ValueError(f'<{element.tag.rpartition("}")[2]}> has no {path}')
    return found


def _seconds(element: ET.Element, path: str) -> float:
    duration = _find(element, path)
    total = 0.0
    for tag, unit in (('sec', 1.0), ('nanosec', 1e-9)):
        part = duration.find(f'dds:{tag}', _NS)
        text = '' if part is None or part.text is None else part.text.strip()
        if text.startswith('DURATION_INFINI'):
            return math.inf
        total += int(text or 0) * unit
    return total


def read_profile(path: Path = PROFILE_FILE) -> DdsProfile:
    """The settings of the profiles file ``path`` (default: the line's).

    Raises
    ------
    ValueError
        A default profile or one of the settings is missing.
    OSError, xml.etree.ElementTree.ParseError
        The file cannot be read or is not XML.
    """
    root = ET.parse(path).getroot()
    participant = _default_profile(root, 'participant')
    writer = _default_profile(root, 'data_writer')
    reader = _default_profile(root, 'data_reader')
    discovery = 'rtps/builtin/discovery_config'
    return DdsProfile(
        heartbeat_period=_seconds(writer, 'times/heartbeat_period'),
        nack_response_delay=_seconds(writer, 'times/nack_response_delay'),
        heartbeat_response_delay=_seconds(reader, 'times/heartbeat_response_delay'),
        lease_duration=_seconds(participant, f'{discovery}/leaseDuration'),
        lease_announcement=_seconds(participant, f'{discovery}/leaseAnnouncement'),
        send_buffer=int(str(_find(participant, 'rtps/sendSocketBufferSize').text)),
        receive_buffer=int(str(_find(participant, 'rtps/listenSocketBufferSize').text)),
    )


PROFILE: Final = read_profile()
"""The line's profile (:data:`PROFILE_FILE`)."""

HEARTBEAT_PERIOD: Final = PROFILE.heartbeat_period
"""Seconds between the heartbeats of a writer with unacknowledged samples: the time a lost sample waits."""

LEASE_DURATION: Final = PROFILE.lease_duration
"""Seconds after which a participant not heard from leaves the graph (a killed process does)."""

LEASE_ANNOUNCEMENT: Final = PROFILE.lease_announcement
"""Seconds between a participant's announcements of itself."""


def line_profile_text(partition: str) -> str:
    """The line's profiles (:data:`PROFILE_FILE`) in the line's partition, as Fast DDS's ``partitions`` property.

    The default DataReader is in ``partition`` only: it hears the line's writers alone. The
    default DataWriter is in ``partition`` and the default partition: everyone hears it. The
    reader of the ROS graph's own topic (:data:`GRAPH_TOPIC`, found by rmw_fastrtps under a
    profile of that name) is in both, so the line still knows the names of nodes outside it.
    """
    ET.register_namespace('', _NS['dds'])
    root = ET.parse(PROFILE_FILE).getroot()
    reader = _default_profile(root, 'data_reader')
    graph_reader = copy.deepcopy(reader)
    del graph_reader.attrib['is_default_profile']
    graph_reader.set('profile_name', GRAPH_TOPIC)
    profiles = _find(root, 'profiles')
    profiles.append(graph_reader)
    for element, partitions in (
        (_default_profile(root, 'data_writer'), f';{partition}'),
        (reader, partition),
        (graph_reader, f';{partition}'),
    ):
        policy = ET.SubElement(element, f'{{{_NS["dds"]}}}propertiesPolicy')
        prop = ET.SubElement(ET.SubElement(policy, f'{{{_NS["dds"]}}}properties'), f'{{{_NS["dds"]}}}property')
        ET.SubElement(prop, f'{{{_NS["dds"]}}}name').text = 'partitions'
        ET.SubElement(prop, f'{{{_NS["dds"]}}}value').text = partitions
    root.insert(0, ET.Comment(f' folder_line: the line profile in partition {partition} (dds_profile.py) '))
    return ET.tostring(root, encoding='unicode', xml_declaration=True)


def _profile_folder() -> Path:
    """Where this user's line profiles go: ``folder_line-<uid>`` in ``XDG_RUNTIME_DIR`` or the temp folder."""
    return Path(os.environ.get('XDG_RUNTIME_DIR') or tempfile.gettempdir()) / f'folder_line-{os.getuid()}'


def _profile_dir() -> Path:
    """:func:`_profile_folder`, made if missing (0700) and checked to be this user's alone: before a write."""
    folder = _profile_folder()
    folder.mkdir(mode=0o700, exist_ok=True)
    st = os.lstat(folder)
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid() or st.st_mode & 0o077:
        msg = f'{folder} is not a private folder of this user: remove it, or set XDG_RUNTIME_DIR to one'
        raise OSError(msg)
    return folder


def _profile_path(partition: str) -> Path:
    return _profile_folder() / f'{partition}.xml'


def _write_profile(partition: str) -> Path:
    """The profiles file of ``partition``, written (atomically: other processes may be reading it) unless it
    already holds what this version writes."""
    path = _profile_dir() / f'{partition}.xml'
    text = line_profile_text(partition)
    with contextlib.suppress(OSError):
        if path.read_text(encoding='utf-8') == text:
            return path
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix='.tmp')
    with os.fdopen(fd, 'w', encoding='utf-8') as f:
        f.write(text)
    os.replace(tmp, path)
    return path


def _ours(path: str) -> bool:
    """Whether ``path`` is the shipped profile or one :func:`use_line_profile` wrote (not the user's own)."""
    return Path(path) == PROFILE_FILE or Path(path).parent == _profile_folder()


def line_partition(environ: Mapping[str, str] = os.environ) -> str | None:
    """The partition of the line that processes started with ``environ`` join, or None: an *open* line
    (no key, or the user's own profiles file, which :func:`use_line_profile` leaves alone).

    Raises
    ------
    ParameterError
        ``environ`` holds a key that is not one.
    """
    key = read_key(environ)
    if key is None:
        return None
    partition = partition_name(key)
    named = environ.get(PROFILES_FILE_VARIABLE, '')
    return partition if named and Path(named) == _profile_path(partition) else None


def use_line_profile(environ: MutableMapping[str, str] = os.environ) -> str | None:
    """Have the participants made after this call (``rclpy.init``) load the line's profile.

    Sets ``FASTDDS_DEFAULT_PROFILES_FILE`` in ``environ`` to the line's profiles file, unless
    the user named a profiles file (that variable, or Fast DDS 2's
    ``FASTRTPS_DEFAULT_PROFILES_FILE``), or ``RMW_IMPLEMENTATION`` is not Fast DDS. With a key
    (:data:`folder_line.ros.line_key.KEY_VARIABLE`) that file is the line's profile with the
    key's partition (:func:`line_profile_text`), written once per key to a private folder of
    this user; without one it is :data:`PROFILE_FILE`. Fast DDS loads the file once per
    process, at its first participant; processes started later with a copy of ``environ``
    load it too. A ``DEFAULT_FASTDDS_PROFILES.xml`` in the working directory is loaded after
    it and its default profiles take precedence.

    Parameters
    ----------
    environ : MutableMapping[str, str], optional
        The environment to change (default ``os.environ``: this process and its children).

    Returns
    -------
    str or None
        The profiles file the participants will load (the user's, if set), or None when
        the RMW is not Fast DDS.

    Raises
    ------
    ParameterError
        ``environ`` holds a key that is not one.
    OSError
        The private folder cannot be made or written.
    """
    if environ.get('RMW_IMPLEMENTATION', '') not in ('', *_FASTDDS_RMWS):
        return None
    key = read_key(environ)
    for variable in _USER_VARIABLES:
        if environ.get(variable) and not _ours(environ[variable]):
            return environ[variable]
    path = PROFILE_FILE if key is None else _write_profile(partition_name(key))
    environ[PROFILES_FILE_VARIABLE] = str(path)
    return str(path)
