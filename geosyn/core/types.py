"""Shared array type aliases (float64 everywhere)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]
"""A float64 array of any shape."""

Vector = npt.NDArray[np.float64]
"""A float64 array of shape (n,)."""

Matrix = npt.NDArray[np.float64]
"""A float64 array of shape (n, m)."""
