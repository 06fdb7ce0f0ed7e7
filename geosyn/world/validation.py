"""Validation of world geometry: the one set of tolerances for shapes, poses and payloads.

Plain values (vectors, lengths, offsets) are checked by `geosyn.core.validation`; the
checks here add what is geometric (rotation matrices, unit vectors, rigid-body inertias)
and raise `InvalidGeometry` naming the field (``"Box.rotation"``), the value and what is
allowed. Shapes, payloads, the obstacle shaping term and the simulation scene all go
through these, so a shape accepted by one is accepted by all.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Matrix
from geosyn.core.validation import check_float, check_positive, check_vec3
from geosyn.world.errors import InvalidGeometry

ROTATION_TOL = 1e-9
"""Largest entry of ``R^T R - I`` of an accepted rotation matrix."""

UNIT_TOL = 1e-9
"""Largest ``| ||n|| - 1 |`` of an accepted unit vector."""

INERTIA_SYMMETRY_TOL = 1e-12
"""Largest asymmetry of an accepted inertia, relative to its largest entry."""

INERTIA_TRIANGLE_TOL = 1e-12
"""Relative slack of the triangle inequality ``I1 + I2 >= I3`` of principal moments."""

_T = TypeVar("_T")


def _geometric(check: Callable[..., _T], x: object, name: str, *args: object, **kw: object) -> _T:
    """Run a `geosyn.core.validation` check, reporting a failure as `InvalidGeometry`."""
    try:
        return check(x, *args, **kw)
    except InvalidArgument as err:
        raise InvalidGeometry(str(err), name, x) from err


def point(x: object, name: str) -> tuple[float, float, float]:
    """A finite (3,) point or vector [m] as a tuple of floats.

    Raises:
        InvalidGeometry: not a finite (3,) vector.
    """
    return _geometric(check_vec3, x, name, name)


def nonnegative(x: object, name: str, *, unit: str, strict: bool = False) -> float:
    """A finite size (a length, a mass) >= 0, or > 0 if ``strict``.

    Args:
        x: candidate number.
        name: field name for the message.
        unit: its unit for the message, e.g. ``"m"``.
        strict: refuse 0.

    Raises:
        InvalidGeometry: not a number, not finite, or out of range.
    """
    if strict:
        return _geometric(check_positive, x, name, name, unit)
    return _geometric(check_float, x, name, name, low=0.0, unit=unit)


def offset(x: object, name: str) -> float:
    """A finite signed distance [m].

    Raises:
        InvalidGeometry: not a finite number.
    """
    return _geometric(check_float, x, name, name, unit="m")


def unit_vector(x: object, name: str) -> tuple[float, float, float]:
    """A (3,) unit vector (norm 1 within `UNIT_TOL`), returned as given (not renormalised).

    Raises:
        InvalidGeometry: not a finite (3,) vector of unit norm.
    """
    n = point(x, name)
    if abs(float(np.linalg.norm(n)) - 1.0) > UNIT_TOL:
        raise InvalidGeometry(
            f"{name} must be a unit vector (norm 1 within {UNIT_TOL}), got {n}", name, x
        )
    return n


def rotation(x: object, name: str) -> Matrix:
    """A (3, 3) rotation matrix: ``R^T R = I`` within `ROTATION_TOL` and ``det R = +1``.

    Returns:
        (3, 3) float64 copy of ``x``.

    Raises:
        InvalidGeometry: not a finite (3, 3) proper rotation matrix.
    """
    allowed = f"a (3, 3) rotation matrix (R^T R = I within {ROTATION_TOL}, det +1)"
    try:
        R = np.array(x, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InvalidGeometry(f"{name} must be {allowed}, got {x!r}", name, x) from err
    if (
        R.shape != (3, 3)
        or not np.all(np.isfinite(R))
        or np.max(np.abs(R.T @ R - np.eye(3))) > ROTATION_TOL
        or np.linalg.det(R) < 0.0
    ):
        raise InvalidGeometry(f"{name} must be {allowed}, got {x!r}", name, x)
    return R


def inertia(x: object, name: str) -> Matrix:
    """A rigid body's rotational inertia about its centre of mass [kg m^2].

    Symmetric (within `INERTIA_SYMMETRY_TOL`, relative), positive definite, and with
    principal moments satisfying the triangle inequality ``I1 + I2 >= I3`` (within
    `INERTIA_TRIANGLE_TOL`): the conditions for some rigid body to have it.

    Returns:
        (3, 3) float64 copy of ``x``.

    Raises:
        InvalidGeometry: any condition fails; the message says which.
    """
    try:
        inertia_c = np.array(x, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InvalidGeometry(
            f"{name} must be a (3, 3) matrix [kg m^2], got {x!r}", name, x
        ) from err
    if inertia_c.shape != (3, 3) or not np.all(np.isfinite(inertia_c)):
        raise InvalidGeometry(f"{name} must be a finite (3, 3) matrix [kg m^2], got {x!r}", name, x)
    scale = max(float(np.max(np.abs(inertia_c))), 1e-300)
    if np.max(np.abs(inertia_c - inertia_c.T)) > INERTIA_SYMMETRY_TOL * scale:
        raise InvalidGeometry(f"{name} must be symmetric, got {inertia_c.tolist()}", name, x)
    eig = np.linalg.eigvalsh(inertia_c)
    if eig[0] <= 0.0:
        raise InvalidGeometry(
            f"{name} must be positive definite, got eigenvalues {eig.tolist()} "
            f"of {inertia_c.tolist()}",
            name,
            x,
        )
    if eig[0] + eig[1] < eig[2] * (1.0 - INERTIA_TRIANGLE_TOL):
        raise InvalidGeometry(
            f"{name} principal moments {eig.tolist()} violate the triangle inequality "
            "(I1 + I2 >= I3); no rigid body has this inertia",
            name,
            x,
        )
    return inertia_c


__all__ = [
    "INERTIA_SYMMETRY_TOL",
    "INERTIA_TRIANGLE_TOL",
    "ROTATION_TOL",
    "UNIT_TOL",
    "inertia",
    "nonnegative",
    "offset",
    "point",
    "rotation",
    "unit_vector",
]
