"""rosbag2 bags (MCAP): message types, metadata.yaml, segment writer, reader, repair."""
