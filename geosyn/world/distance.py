"""Signed distances from points to shapes: numeric (numpy) and symbolic (CasADi).

The signed distance is the Euclidean distance to the shape's surface, positive outside
and negative inside. `signed_distance` evaluates it for a batch of points with one exact
formula per shape. `rounded_box_distance` is the symbolic form every shape shares through
its rounded-box parameters (`geosyn.world.shapes`): with ``p = R^T (x - c)``,

.. math::
    \\mathrm{sd}(x) = \\lVert p - \\mathrm{clamp}(p, -h, h) \\rVert
                    + \\min(\\max_i (|p_i| - h_i), 0) - r

which is the exact Euclidean signed distance of the rounded box. It agrees with
`signed_distance` to round-off outside the shape (a `HalfSpace`: within
`HALFSPACE_EXTENT` of the plane's point closest to the origin); inside a box or half-space
it is larger by the 1e-12 m that keeps its gradient finite there. Smoothness: a sphere's distance is smooth outside its
centre; a capsule's and a box's are C1 outside, with curvature jumps where the closest
point moves between the segment and an end cap, or between faces, edges and corners.
"""

from __future__ import annotations

from collections.abc import Callable

import casadi as ca
import numpy as np

from geosyn.core.types import Array, Vector
from geosyn.world import shapes


def _sphere(s: shapes.Sphere, p: Array) -> Vector:
    return np.linalg.norm(p - np.asarray(s.center), axis=1) - s.radius


def _box(s: shapes.Box, p: Array) -> Vector:
    # rotation is world-from-box, so (p - c) @ R is R^T (p - c) row by row
    local = np.abs((p - np.asarray(s.center)) @ np.asarray(s.rotation)) - np.asarray(s.half_extents)
    outside = np.linalg.norm(np.maximum(local, 0.0), axis=1)
    inside = np.minimum(local.max(axis=1), 0.0)
    return outside + inside


def _capsule(s: shapes.Capsule, p: Array) -> Vector:
    a, b = np.asarray(s.p0), np.asarray(s.p1)
    ab = b - a
    denom = float(ab @ ab)
    t = np.zeros(len(p)) if denom == 0.0 else np.clip((p - a) @ ab / denom, 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1) - s.radius


def _cylinder(s: shapes.Cylinder, p: Array) -> Vector:
    local = (p - np.asarray(s.center)) @ np.asarray(s.rotation)
    u = np.column_stack(
        [np.hypot(local[:, 0], local[:, 1]) - s.radius, np.abs(local[:, 2]) - s.half_length]
    )
    return np.linalg.norm(np.maximum(u, 0.0), axis=1) + np.minimum(u.max(axis=1), 0.0)


def _halfspace(s: shapes.HalfSpace, p: Array) -> Vector:
    return p @ np.asarray(s.normal) - s.offset


_NUMERIC: dict[type, Callable[..., Vector]] = {
    shapes.Sphere: _sphere,
    shapes.Box: _box,
    shapes.Capsule: _capsule,
    shapes.Cylinder: _cylinder,
    shapes.HalfSpace: _halfspace,
}


def signed_distance(shape: shapes.Shape, points: Array) -> Vector:
    """Signed distances of points to a shape (exact; negative inside). O(S).

    Args:
        shape: a `Sphere`, `Box`, `Capsule`, `Cylinder` or `HalfSpace`.
        points: (S, 3) points in the world [m] (a single (3,) point is taken as (1, 3)).

    Returns:
        (S,) signed distances [m].

    Raises:
        InvalidGeometry: ``shape`` is not a shape.
    """
    shapes.check_shape(shape, "shape")
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return _NUMERIC[type(shape)](shape, p)


def rounded_box_distance() -> ca.Function:
    """CasADi function ``(x (3), prm (16)) -> (sd, d sd / dx (3))`` of the rounded box.

    ``prm`` holds a shape's `rounded_box` parameters (a symbol or numbers), ``x`` the
    point [m]; ``sd`` [m] is the signed distance in the module docstring. Builds a new
    function on each call (allocates); call it once and evaluate it symbolically.
    """
    x = ca.SX.sym("x", 3)
    prm = ca.SX.sym("prm", shapes.ROUNDED_BOX_SIZE)
    c = prm[0:3]
    R = ca.reshape(prm[3:12], 3, 3).T  # row-major storage
    h = prm[12:15]
    r = prm[15]
    p = ca.mtimes(R.T, x - c)
    # Closest point of the box, by branches rather than fabs/fmax: at a tie (h_i = 0 and
    # p_i = 0, e.g. a planar scene) the outer branch is taken, so the derivatives of a
    # sphere's or capsule's distance are exact there too (AD through fabs at 0 is not).
    b = ca.vertcat(
        *[ca.if_else(p[i] >= h[i], h[i], ca.if_else(p[i] <= -h[i], -h[i], p[i])) for i in range(3)]
    )
    # The 1e-24 m^2 keeps the gradient finite (zero) at and inside the surface; it is below
    # round-off of any clearance above 1e-8 m.
    outside = ca.sqrt(ca.sumsqr(p - b) + 1e-24)
    inside = ca.fmin(ca.mmax(ca.fabs(p) - h), 0.0)
    sd = outside + inside - r
    return ca.Function("rounded_box_distance", [x, prm], [sd, ca.gradient(sd, x)])
