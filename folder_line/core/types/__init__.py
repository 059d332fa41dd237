"""What the core's layers share, below all but the numerics: the line's events and joint samples
(:mod:`~folder_line.core.types.events`) and the machine sections that are not a mechanism of their own
(:mod:`~folder_line.core.types.machines`). The layers run ``numerics -> types -> mechanisms -> effects ->
line -> supervision`` (``test/test_architecture.py``)."""
