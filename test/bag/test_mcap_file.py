"""``McapFile`` writes the bytes python mcap's own ``Writer`` writes for the same records."""

from __future__ import annotations

import io

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from folder_line.bag.mcap_file import McapFile


def write(out: McapFile | Writer, messages: list[tuple[int, int, bytes]], flush_at: int) -> None:
    schema = out.register_schema('std_msgs/msg/String', 'ros2msg', b'string data')
    channels = [out.register_channel(f'/t{i}', 'cdr', schema, {'offered_qos_profiles': '[]'}) for i in range(3)]
    out.add_metadata('rosbag2', {'k': 'v'})
    for i, (channel, log_ns, data) in enumerate(messages):
        if i == flush_at:
            out.flush()
        out.add_message(channels[channel], log_ns, data, log_ns + 1, i)
    out.finish()


@pytest.mark.parametrize('chunk_size', [1, 4096, 1 << 20])
def test_the_bytes_equal_python_mcaps_writer(chunk_size: int) -> None:
    rng = np.random.default_rng(7)
    messages = [(int(rng.integers(3)), 1_000_000 * i, rng.bytes(int(rng.integers(0, 300)))) for i in range(2000)]
    ours, theirs = io.BytesIO(), io.BytesIO()
    write(McapFile(ours, chunk_size=chunk_size, profile='ros2', library='x'), messages, flush_at=700)
    reference = Writer(theirs, chunk_size=chunk_size, compression=CompressionType.ZSTD)
    reference.start(profile='ros2', library='x')
    write(reference, messages, flush_at=700)
    assert ours.getvalue() == theirs.getvalue()
    ours.seek(0)
    read = [(m.channel_id - 1, m.log_time, m.data) for _, _, m in make_reader(ours).iter_messages(log_time_order=False)]
    assert read == messages
