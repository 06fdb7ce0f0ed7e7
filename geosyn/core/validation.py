"""Argument checks shared by every layer: the one place geosyn validates plain values.

Each check returns the value in its canonical type or raises `geosyn.core.InvalidArgument`
with a message naming the argument, the value given and what is allowed. Every layer
(robots, world, metrics, controllers, sim, experiments) uses these instead of writing its
own, so one kind of value is always checked, and reported, the same way: complex numbers,
booleans, text and objects are refused (never cast: ``np.asarray(x, float)`` would drop an
imaginary part or read a mask as 0/1), and a vector must be finite with a finite squared
norm (entries below about 1e154), so the arithmetic that follows cannot overflow.
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


def _describe(x: object) -> str:
    """A short repr of a value for a message (a huge array is not printed whole)."""
    text = repr(x)
    return text if len(text) <= 200 else text[:200] + "..."


def check_real_array(x: object, name: str) -> np.ndarray:
    """Return ``x`` as a float64 array (any shape), refusing what is not real numbers.

    Complex values, booleans (a mask is not a vector), text, bytes and objects raise;
    finiteness and shape are the caller's to check.

    Args:
        x: candidate array or scalar.
        name: argument name for the error message.
    """
    if isinstance(x, (str, bytes)) or _is_complex(x):
        raise InvalidArgument(f"{name} must be a real (float) array, got {_describe(x)}")
    if _is_bool(x):
        raise InvalidArgument(f"{name} must be a float array, got booleans {_describe(x)}")
    try:
        arr = np.asarray(x)
        if arr.dtype.kind not in "iuf":  # objects, text, nested ragged lists
            raise TypeError(f"dtype {arr.dtype}")
        return arr.astype(np.float64, copy=False)
    except (TypeError, ValueError, OverflowError) as err:
        raise InvalidArgument(f"{name} must be a real (float) array, got {_describe(x)}") from err


def check_vector(x: object, n: int, name: str) -> Vector:
    """Return ``x`` as a finite float64 (n,) array, or raise `InvalidArgument`.

    A finite float64 (n,) ndarray is returned as is (no copy, O(n)); anything else is
    converted and checked. Complex and boolean input is refused, not cast. The squared
    norm must be finite too (every entry below about 1e154): such a vector's products
    overflow (an ``OverflowError`` or inf downstream), so it is refused here, once.

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
        raise InvalidArgument(f"{name} must be real (float), got complex values {_describe(x)}")
    if _is_bool(x):
        raise InvalidArgument(
            f"{name} must be a float array of shape ({n},), got booleans {_describe(x)}"
        )
    try:
        arr = check_real_array(x, name)
    except InvalidArgument as err:
        raise InvalidArgument(
            f"{name} must be a float array of shape ({n},), got {_describe(x)}"
        ) from err
    if arr.shape != (n,):
        raise InvalidArgument(f"{name} must have shape ({n},), got shape {arr.shape}")
    return _finite_within_float64(arr, name)


def _finite_within_float64(arr: np.ndarray, name: str) -> np.ndarray:
    """``arr`` if every entry is finite and its sum of squares is within float64 (entries
    below about 1e154: their products would overflow downstream), else raise
    `InvalidArgument` naming ``name``."""
    if not np.all(np.isfinite(arr)):
        raise InvalidArgument(f"{name} must be finite, got {_describe(arr)}")
    with np.errstate(over="ignore"):
        squared = float(np.vdot(arr, arr))
    if not math.isfinite(squared):
        raise InvalidArgument(
            f"{name} is too large to compute with: max |{name}_i| = {np.abs(arr).max():.3g};"
            f" allowed: a sum of squares within float64 (entries below about 1e154)"
        )
    return arr


def check_rows(x: object, n: int, name: str) -> np.ndarray:
    """Return ``x`` as a finite float64 (K, n) array (K >= 0 rows of length n), or raise
    `InvalidArgument`.

    A C-contiguous float64 (K, n) ndarray with a finite sum of squares is returned as is
    (no copy, one O(K n) reduction); anything else is converted and checked as in
    `check_vector`, the whole array at once (entries below about 1e154).

    Args:
        x: candidate (K, n) array, e.g. K configurations of an n-joint robot.
        n: expected row length.
        name: argument name for the error message.
    """
    if (
        type(x) is np.ndarray
        and x.ndim == 2
        and x.shape[1] == n
        and x.dtype == np.float64
        and x.flags.c_contiguous
        and math.isfinite(float(np.vdot(x, x)))
    ):
        return x
    if _is_complex(x) or _is_bool(x):
        raise InvalidArgument(
            f"{name} must be a real float array of shape (K, {n}), got {_describe(x)}"
        )
    arr = np.ascontiguousarray(check_real_array(x, name))
    if arr.ndim != 2 or arr.shape[1] != n:
        raise InvalidArgument(f"{name} must have shape (K, {n}), got shape {arr.shape}")
    return _finite_within_float64(arr, name)


def check_scalar_or_vector(x: object, n: int, name: str, *, low: float = -math.inf) -> Vector:
    """Return a scalar (broadcast) or (n,) ``x`` as a new finite float64 (n,) array >= low.

    Complex, boolean and text values are refused, not cast (e.g. a gain ``900 + 1j``).

    Args:
        x: scalar or (n,) array.
        n: length.
        name: argument name for the error message.
        low: smallest allowed entry.
    """
    arr = check_real_array(x, name)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise InvalidArgument(
            f"{name} must be a scalar or an array of shape ({n},), got shape {arr.shape}"
        )
    if not np.all(np.isfinite(arr)) or np.any(arr < low):
        raise InvalidArgument(f"{name} must be finite and >= {low:g}, got {_describe(arr)}")
    return arr.copy()


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
        raise InvalidArgument(f"{name} must be {allowed}, got {_describe(x)}")
    try:
        val = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError) as err:  # 10**400 overflows float
        raise InvalidArgument(f"{name} must be {allowed}, got {_describe(x)}") from err
    inside = (val > low if low_open else val >= low) and val <= high
    if not (math.isfinite(val) and inside):
        raise InvalidArgument(f"{name} must be {allowed}, got {_describe(x)}")
    return val


def check_positive(x: object, name: str, unit: str = "") -> float:
    """Return ``x`` as a finite float > 0, or raise `InvalidArgument`.

    Args:
        x: candidate number.
        name: argument name for the error message.
        unit: unit for the message.
    """
    if isinstance(x, (bool, str, bytes, complex, np.bool_)):
        raise InvalidArgument(f"{name} must be a finite number > 0, got {_describe(x)}")
    try:
        val = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError) as err:  # 10**400 overflows float
        raise InvalidArgument(f"{name} must be a finite number > 0, got {_describe(x)}") from err
    if not (math.isfinite(val) and val > 0.0):
        suffix = f" [{unit}]" if unit else ""
        raise InvalidArgument(f"{name} must be a finite number > 0{suffix}, got {_describe(x)}")
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
        raise InvalidArgument(f"{name} must be {allowed}, got {_describe(x)}")
    val = int(x)
    if (low is not None and val < low) or (high is not None and val > high):
        raise InvalidArgument(f"{name} must be {allowed}, got {_describe(x)}")
    return val


def check_choice(x: object, allowed: Sequence[str], name: str) -> str:
    """Return ``x`` if it is one of the strings ``allowed``, or raise `InvalidArgument`.

    Args:
        x: candidate value.
        allowed: the allowed strings.
        name: argument name for the error message.
    """
    if not isinstance(x, str) or x not in allowed:
        raise InvalidArgument(
            f"{name} must be one of {', '.join(map(repr, allowed))}, got {_describe(x)}"
        )
    return x
