"""Obstacles drawn in a figure: each `geosyn.world` shape as its silhouette, the outline of
its orthogonal projection onto a plane of two world axes (a procedure's front or top view).

A sphere's silhouette is its circle; a box's, the convex hull of its 8 corners projected; a
capsule's, the hull of the two end discs; a cylinder's, the hull of its two rim circles
(each `RIM_POINTS` points, so the polygon lies inside the true outline by at most
``1 - cos(pi / RIM_POINTS)`` = 0.12 % of the radius). A half-space has no bounded
silhouette: one whose normal lies in the view plane is drawn as its boundary line, others
(a floor seen from above) fill the view and are left out, which `draw_obstacles` returns.
A shape with no area in the view (a flat box seen edge-on) is the segment it covers.
Shapes come from the run's own scene (`geosyn.experiments.run.scene.build_obstacles`:
``scene.obstacles`` and a MuJoCo scene file's geoms), so the figure shows what the
planner and the simulation saw.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.world import Box, Capsule, Cylinder, HalfSpace, Sphere
from geosyn.world.shapes import Shape

__all__ = ["RIM_POINTS", "draw_obstacles", "silhouette"]

RIM_POINTS = 64
"""Points on a circle (a capsule's end disc, a cylinder's rim) of a silhouette."""

_STYLE = {"color": "0.6", "alpha": 0.6}


def _circle(n: int = RIM_POINTS) -> np.ndarray:
    """(n, 2) the unit circle's points."""
    a = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    return np.column_stack([np.cos(a), np.sin(a)])


def _hull(points: np.ndarray) -> np.ndarray:
    """(K, 2) the convex hull's vertices of ``points`` (N, 2), counter-clockwise; for points
    on one line (a flat box seen edge-on) the segment's two ends, (2, 2)."""
    from scipy.spatial import ConvexHull, QhullError  # ~0.13 s: imported where drawn

    try:
        return points[ConvexHull(points).vertices]
    except QhullError:  # no area: a segment (or a point)
        centred = points - points.mean(axis=0)
        direction = np.linalg.svd(centred, full_matrices=False)[2][0]
        along = centred @ direction
        return points[[int(np.argmin(along)), int(np.argmax(along))]]


def silhouette(shape: Shape, axes: tuple[int, int] = (1, 2)) -> np.ndarray | None:
    """(K, 2) [m] the outline (counter-clockwise) of ``shape`` projected orthogonally onto
    the plane of the world ``axes`` (two of 0, 1, 2: x, y, z; (1, 2) is the front view,
    y right and z up), or None for a `Sphere` (its circle: centre and radius) and a
    `HalfSpace` (unbounded).

    Raises:
        InvalidArgument: ``axes`` not two different indices of 0, 1, 2.
    """
    if len(axes) != 2 or axes[0] == axes[1] or not set(axes) <= {0, 1, 2}:
        raise InvalidArgument(f"axes: two different world axes of 0, 1, 2, got {axes!r}")
    ix = list(axes)
    if isinstance(shape, (Sphere, HalfSpace)):
        return None
    if isinstance(shape, Box):
        signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
        corners = (
            np.asarray(shape.center) + (signs * shape.half_extents) @ np.asarray(shape.rotation).T
        )
        return _hull(corners[:, ix])
    if isinstance(shape, Capsule):
        ends = np.array([shape.p0, shape.p1])[:, ix]
        disc = shape.radius * _circle()
        return _hull(np.concatenate([ends[0] + disc, ends[1] + disc]))
    if isinstance(shape, Cylinder):
        R = np.asarray(shape.rotation)
        rim = shape.radius * _circle() @ R[:, :2].T  # (N, 3) round the axis
        centers = np.asarray(shape.center) + np.outer((-1.0, 1.0), shape.half_length * R[:, 2])
        points = np.concatenate([centers[0] + rim, centers[1] + rim])
        return _hull(points[:, ix])
    raise InvalidArgument(f"shape: a geosyn.world shape, got {type(shape).__name__}")


def draw_obstacles(ax: Any, shapes: Sequence[Shape], axes: tuple[int, int] = (1, 2)) -> int:
    """Draw every shape of ``shapes`` on the matplotlib ``ax`` as its `silhouette` in the
    plane of the world ``axes`` (grey); returns how many were left out (half-spaces whose
    normal leaves the plane: they fill the view)."""
    from matplotlib.patches import Circle, Polygon  # matplotlib: imported where drawn

    left_out = 0
    for s in shapes:
        if isinstance(s, Sphere):
            ax.add_patch(Circle(tuple(np.asarray(s.center)[list(axes)]), s.radius, **_STYLE))
        elif isinstance(s, HalfSpace):
            n = np.asarray(s.normal)
            other = 3 - axes[0] - axes[1]
            if abs(n[other]) > 1e-9:
                left_out += 1
                continue
            point = s.offset * n  # the plane's point nearest the origin
            along = np.array([-n[axes[1]], n[axes[0]]])  # in the view plane
            p = point[list(axes)]
            ax.axline(tuple(p), tuple(p + along), color=_STYLE["color"], lw=2.0)
        else:
            outline = silhouette(s, axes)
            ax.add_patch(Polygon(outline, closed=True, **_STYLE))  # type: ignore[arg-type]
    return left_out
