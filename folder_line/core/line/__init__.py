"""The batch line: scenes and machine sections, events, the per-machine simulators, the line model."""
