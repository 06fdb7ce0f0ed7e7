"""Argument checks shared by every layer: the one place geosyn validates plain values.

Each check returns the value in its canonical type or raises `geosyn.core.InvalidArgument`
with a message naming the argument, the value given and what is allowed. Every layer
(robots, world, metrics, controllers, sim, experiments) uses these instead of writing its
own, so one kind of value is always checked, and reported, the same way.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector


def _is_complex(x: object) -> bool:
    """True for complex scalars and arrays (refused rather than silently cast to real)."""
    return isinstance(x, complex) or (
        isinstance(x, (np.ndarray, np.generic)) and np.iscomplexobj(x)
    )


def _is_bool(x: object) -> bool:
    """True for booleans, boolean arrays and sequences holding a boolean (refused rather
    than read as 0/1: a mask passed where a vector is expected is a bug)."""
    if isinstance(x, (bool, np.bool_)):
        return True
    if isinstance(x, (np.ndarray, np.generic)):
        return x.dtype == np.bool_
    if isinstance(x, (list, tuple)):
        return any(isinstance(e, (bool, np.bool_)) for e in x)
    return False


def check_vector(x: object, n: int, name: str) -> Vector:
    """Return ``x`` as a finite float64 (n,) array, or raise `InvalidArgument`.

    A finite float64 (n,) ndarray is returned as is (no copy, O(n)); anything else is
    converted and checked. Complex and boolean input is refused, not cast.

    Args:
        x: candidate vector.
        n: expected length.
        name: argument name for the error message.
    """
    if (
        type(x) is np.ndarray
        and x.shape == (n,)
        and x.dtype == np.float64
        and math.isfinite(x.dot(x))
    ):
        return x
    if _is_complex(x):
        raise InvalidArgument(f"{name} must be real (float), got complex values {x!r}")
    if _is_bool(x):
        raise InvalidArgument(f"{name} must be a float array of shape ({n},), got booleans {x!r}")
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InvalidArgument(f"{name} must be a float array of shape ({n},), got {x!r}") from err
    if arr.shape != (n,):
        raise InvalidArgument(f"{name} must have shape ({n},), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InvalidArgument(f"{name} must be finite, got {arr}")
    return arr


def check_vec3(x: object, name: str) -> tuple[float, float, float]:
    """Return ``x`` as a finite 3-vector (a tuple of floats), or raise `InvalidArgument`.

    Args:
        x: candidate (3,) vector, e.g. a position [m] or an axis.
        name: argument name for the error message.
    """
    arr = check_vector(x, 3, name)
    return (float(arr[0]), float(arr[1]), float(arr[2]))


def check_float(
    x: object,
    name: str,
    *,
    low: float = -math.inf,
    high: float = math.inf,
    low_open: bool = False,
    unit: str = "",
) -> float:
    """Return ``x`` as a finite float in ``[low, high]`` (``(low, high]`` if ``low_open``).

    Booleans, strings and complex numbers are refused.

    Args:
        x: candidate number.
        name: argument name for the error message.
        low: smallest allowed value.
        high: largest allowed value.
        low_open: exclude ``low`` itself.
        unit: unit for the message, e.g. ``"s"``.
    """
    left = "(" if low_open else "["
    allowed = f"a finite number in {left}{low:g}, {high:g}]" + (f" [{unit}]" if unit else "")
    if isinstance(x, (bool, str, bytes, complex, np.bool_)) or _is_complex(x):
        raise InvalidArgument(f"{name} must be {allowed}, got {x!r}")
    try:
        val = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError) as err:
        raise InvalidArgument(f"{name} must be {allowed}, got {x!r}") from err
    inside = (val > low if low_open else val >= low) and val <= high
    if not (math.isfinite(val) and inside):
        raise InvalidArgument(f"{name} must be {allowed}, got {x!r}")
    return val


def check_positive(x: object, name: str, unit: str = "") -> float:
    """Return ``x`` as a finite float > 0, or raise `InvalidArgument`.

    Args:
        x: candidate number.
        name: argument name for the error message.
        unit: unit for the message.
    """
    if isinstance(x, (bool, str, bytes, complex, np.bool_)):
        raise InvalidArgument(f"{name} must be a finite number > 0, got {x!r}")
    try:
        val = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError) as err:
        raise InvalidArgument(f"{name} must be a finite number > 0, got {x!r}") from err
    if not (math.isfinite(val) and val > 0.0):
        suffix = f" [{unit}]" if unit else ""
        raise InvalidArgument(f"{name} must be a finite number > 0{suffix}, got {x!r}")
    return val


def check_int(x: object, name: str, *, low: int | None = None, high: int | None = None) -> int:
    """Return ``x`` as an int in ``[low, high]``, or raise `InvalidArgument`.

    Python and numpy integers are accepted; booleans and floats (even 3.0) are not.

    Args:
        x: candidate integer.
        name: argument name for the error message.
        low: smallest allowed value (None: unbounded).
        high: largest allowed value (None: unbounded).
    """
    if low is not None and high is not None:
        allowed = f"an integer in [{low}, {high}]"
    elif low is not None:
        allowed = f"an integer >= {low}"
    elif high is not None:
        allowed = f"an integer <= {high}"
    else:
        allowed = "an integer"
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, np.integer)):
        raise InvalidArgument(f"{name} must be {allowed}, got {x!r}")
    val = int(x)
    if (low is not None and val < low) or (high is not None and val > high):
        raise InvalidArgument(f"{name} must be {allowed}, got {x!r}")
    return val


def check_choice(x: object, allowed: Sequence[str], name: str) -> str:
    """Return ``x`` if it is one of the strings ``allowed``, or raise `InvalidArgument`.

    Args:
        x: candidate value.
        allowed: the allowed strings.
        name: argument name for the error message.
    """
    if not isinstance(x, str) or x not in allowed:
        raise InvalidArgument(f"{name} must be one of {', '.join(map(repr, allowed))}, got {x!r}")
    return x
