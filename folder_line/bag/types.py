"""Message types of a bag: the rosbags typestore of ROS 2 kilted, definitions, CDR serialization.

Messages are serialized by the rosbags typestore, not by ``rclpy.serialization``:
rmw_fastrtps_cpp's serialize_message (kilted wheels) returns some messages with 4 or
8 extra bytes at the end, which rosbags rejects ("CDR message size mismatch"), and
leaves alignment padding uninitialised, so a bag's bytes would depend on memory.
An rclpy message is therefore converted field by field to the typestore's message
(same values; numeric arrays as numpy arrays) and that one is serialized.

No rclpy import: a message class is only looked at through its module and name.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from folder_line.errors import BagError

__all__ = [
    'ROS_DISTRO',
    'message_definition',
    'msgtype_of',
    'serialize',
    'typestore',
]

#: the ROS 2 distribution whose message definitions the bags use (``ros_distro`` in metadata.yaml)
ROS_DISTRO = 'kilted'


@functools.lru_cache(maxsize=1)
def typestore() -> Typestore:
    """The rosbags typestore of ROS 2 kilted (built once)."""
    return get_typestore(Stores.ROS2_KILTED)


@functools.lru_cache(maxsize=64)
def message_definition(msgtype: str) -> tuple[str, str]:
    """``(ros2msg definition text, RIHS01 hash)`` of ``msgtype`` from the kilted typestore.

    Raises
    ------
    BagError
        ``msgtype`` (``'pkg/msg/Type'``) is not in the typestore.
    """
    store = typestore()
    if msgtype not in store.types:
        msg = f'message type {msgtype!r} is not in the rosbags ROS 2 kilted typestore'
        raise BagError(msg)
    text, _ = store.generate_msgdef(msgtype, ros_version=2)
    return text, store.hash_rihs01(msgtype)


@functools.lru_cache(maxsize=64)
def msgtype_of(cls: type) -> str:
    """``'sensor_msgs/msg/JointState'`` for the rclpy message class ``sensor_msgs.msg.JointState``."""
    package, kind = cls.__module__.split('.')[:2]
    return f'{package}/{kind}/{cls.__name__}'


#: an rclpy message's field value -> the typestore's (``Any``: rclpy's messages are untyped, and the typestore's
#: classes take their fields' own types)
_Converter = Callable[[Any], Any]

_NUMPY_DTYPES: dict[str, str] = {
    'bool': 'bool',
    'byte': 'uint8',
    'char': 'uint8',
    'octet': 'uint8',
    'int8': 'int8',
    'uint8': 'uint8',
    'int16': 'int16',
    'uint16': 'uint16',
    'int32': 'int32',
    'uint32': 'uint32',
    'int64': 'int64',
    'uint64': 'uint64',
    'float32': 'float32',
    'float64': 'float64',
}


def _base_converter(name: str) -> _Converter:
    if name in ('string', 'wstring'):
        return str
    if name in ('byte', 'char', 'octet'):  # rclpy gives a byte as bytes of length 1
        return lambda v: v[0] if isinstance(v, (bytes, bytearray)) else int(v)
    if name == 'bool':
        return bool
    if name.startswith('float'):
        return float
    return int


def _field_converter(desc: tuple[Any, Any]) -> _Converter:  # rosbags' FieldDesc, read by its kind
    kind, detail = desc
    if kind == Nodetype.BASE:
        return _base_converter(detail[0])
    if kind == Nodetype.NAME:
        return _converter(detail)
    (sub_kind, sub_detail), _ = detail  # ARRAY or SEQUENCE of one element type
    if sub_kind == Nodetype.BASE and sub_detail[0] in _NUMPY_DTYPES:
        dtype = np.dtype(_NUMPY_DTYPES[sub_detail[0]])

        def to_array(v: Any) -> np.ndarray:
            if isinstance(v, (bytes, bytearray)):
                return np.frombuffer(bytes(v), dtype=np.uint8).copy()
            if isinstance(v, list) and v and isinstance(v[0], (bytes, bytearray)):
                return np.frombuffer(b''.join(v), dtype=np.uint8).copy()
            return np.asarray(v, dtype=dtype)

        return to_array
    element = _field_converter((sub_kind, sub_detail))
    return lambda v: [element(x) for x in v]


@functools.lru_cache(maxsize=64)
def _converter(msgtype: str) -> _Converter:
    """rclpy message of ``msgtype`` -> the rosbags typestore's message (same field values)."""
    store = typestore()
    cls = store.types[msgtype]
    fields = [(name, _field_converter(desc)) for name, desc in store.fielddefs[msgtype][1]]

    def convert(msg: object) -> object:
        return cls(**{name: conv(getattr(msg, name)) for name, conv in fields})

    return convert


def serialize(msg: object, msgtype: str) -> bytes:
    """CDR (little endian) of an rclpy message, serialized by the rosbags typestore as ``msgtype``.

    Raises
    ------
    BagError
        ``msgtype`` is not in the typestore.
    """
    message_definition(msgtype)
    return bytes(typestore().serialize_cdr(_converter(msgtype)(msg), msgtype, little_endian=True))
