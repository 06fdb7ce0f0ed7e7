"""Argument checks shared by every layer above core.

Each raises `geosyn.core.InvalidArgument` with a message naming the argument, the value
and what is allowed. They live here, in the lowest layer above `core` (which holds only
the error base and type aliases), so that metrics, controllers, sim and experiments use
one implementation.
"""

from __future__ import annotations

import math

import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector


def check_vector(x: object, n: int, name: str) -> Vector:
    """Return ``x`` as a finite float64 (n,) array, or raise `InvalidArgument`.

    A finite float64 (n,) ndarray is returned as is (no copy; ~0.5 us); anything else is
    converted and checked.

    Args:
        x: candidate vector.
        n: expected length.
        name: argument name for the error message.
    """
    if (
        x.__class__ is np.ndarray
        and x.shape == (n,)  # type: ignore[attr-defined]
        and x.dtype == np.float64  # type: ignore[attr-defined]
        and math.isfinite(x.dot(x))  # type: ignore[attr-defined]
    ):
        return x  # type: ignore[return-value]
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InvalidArgument(f"{name} must be a float array of shape ({n},), got {x!r}") from err
    if arr.shape != (n,):
        raise InvalidArgument(f"{name} must have shape ({n},), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InvalidArgument(f"{name} must be finite, got {arr}")
    return arr


def check_positive(x: object, name: str) -> float:
    """Return ``x`` as a finite float > 0, or raise `InvalidArgument`.

    Args:
        x: candidate number.
        name: argument name for the error message.
    """
    try:
        val = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError) as err:
        raise InvalidArgument(f"{name} must be a finite number > 0, got {x!r}") from err
    if not (math.isfinite(val) and val > 0.0):
        raise InvalidArgument(f"{name} must be a finite number > 0, got {x!r}")
    return val
