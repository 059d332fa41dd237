"""Configuration: default parameters from ``config/``, scenes, user files and ``--set`` overrides."""
