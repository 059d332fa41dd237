"""Physical and numerical constants shared by the core and its effects."""

from __future__ import annotations

import numpy as np

__all__ = ['EPS', 'G']

#: standard gravity, m/s²
G = 9.80665
#: machine epsilon of float64 (spacing of floats at 1.0)
EPS = float(np.finfo(float).eps)
