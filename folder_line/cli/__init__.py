"""The ``folder-line`` command line and its console outputs (tables, summaries, the papers' report, the monitor)."""
