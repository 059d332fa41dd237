"""Type aliases of the NumPy arrays the core passes around (for annotations)."""

from __future__ import annotations

from typing import TypeAlias

import numpy as np
import numpy.typing as npt

__all__ = ['BoolArray', 'FloatArray', 'FloatOrArray', 'Int8Array', 'IntArray']

#: A float64 array (of any shape).
FloatArray: TypeAlias = npt.NDArray[np.float64]
#: A float or a float64 array; arguments of this type broadcast together.
FloatOrArray: TypeAlias = float | FloatArray
#: An int64 array.
IntArray: TypeAlias = npt.NDArray[np.int64]
#: An int8 array (state and section codes).
Int8Array: TypeAlias = npt.NDArray[np.int8]
#: A boolean array (masks).
BoolArray: TypeAlias = npt.NDArray[np.bool_]
