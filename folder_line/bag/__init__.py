"""rosbag2 bags in MCAP storage: the line's messages written in segments, read back, repaired.

One job per module, each importing only those before it:

- :mod:`~folder_line.bag.types`: the rosbags typestore of ROS 2 kilted, message
  definitions, CDR serialization of rclpy messages;
- :mod:`~folder_line.bag.metadata`: ``metadata.yaml`` (summaries, the YAML text, the
  ``custom_data`` keys) and the segment files' names;
- :mod:`~folder_line.bag.writer`: :class:`BagWriter`, the crash-safe segment writer;
- :mod:`~folder_line.bag.reader`: :func:`read_bag`, :class:`BagContents`, :func:`bag_info_lines`;
- :mod:`~folder_line.bag.repair`: :func:`repair`, which rebuilds ``metadata.yaml`` after a crash.
"""
