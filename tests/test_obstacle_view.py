"""Obstacles drawn in figures (`geosyn.experiments.results.obstacle_view`), against closed
forms of their orthogonal projections: a box's (4 h_y h_z when axis-aligned; a box
turned about the view's normal keeps its area, one turned about an in-plane axis grows
to a hexagon's), a capsule's (stadium: 2 r L + pi r^2), a cylinder's (a disc seen along
its axis, a rectangle 2 r x 2 h seen side-on). Polygon areas by the shoelace formula;
tolerance 1e-12 relative for the polygons that are exact, the inscribed 64-gon's
``sin(2 pi / 64) 64 / (2 pi)`` = 0.16 % for round outlines (rel. 2e-3).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from matplotlib.patches import Circle, Polygon

from geosyn.core.errors import GeosynError
from geosyn.experiments.results.obstacle_view import RIM_POINTS, draw_obstacles, silhouette
from geosyn.experiments.results.plots import figure
from geosyn.world import Box, Capsule, Cylinder, HalfSpace, Sphere
from geosyn.world.pose import rotation_from_rpy

ROUND = math.sin(2.0 * math.pi / RIM_POINTS) * RIM_POINTS / (2.0 * math.pi)  # 64-gon / disc


def _area(p: np.ndarray) -> float:
    x, y = p[:, 0], p[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def test_a_box_projects_to_its_closed_form() -> None:
    h = (0.1, 0.2, 0.3)
    flat = silhouette(Box((0.5, 0.1, 0.4), h))
    assert flat is not None and len(flat) == 4
    assert _area(flat) == pytest.approx(4 * 0.2 * 0.3, rel=1e-12)
    np.testing.assert_allclose(flat.min(axis=0), (0.1 - 0.2, 0.4 - 0.3), atol=1e-15)
    # turned about x (the front view's normal): the same rectangle, turned
    about_x = silhouette(Box((0.5, 0.1, 0.4), h, rotation_from_rpy((0.7, 0.0, 0.0))))
    assert about_x is not None and _area(about_x) == pytest.approx(0.24, rel=1e-12)
    # turned by a about z: seen from the front, y-extent 2 (hx sin a + hy cos a), z 2 hz
    a = 0.6
    about_z = silhouette(Box((0.0, 0.0, 0.0), h, rotation_from_rpy((0.0, 0.0, a))))
    width = 2 * (0.1 * math.sin(a) + 0.2 * math.cos(a))
    assert about_z is not None and _area(about_z) == pytest.approx(width * 0.6, rel=1e-12)


def test_a_flat_box_seen_edge_on_is_the_segment_it_covers() -> None:
    """A panel of zero thickness in y seen from the front: the segment z = 0.2 +- 0.3 at
    y = 0.1 (its two ends, exactly)."""
    edge = silhouette(Box((0.5, 0.1, 0.2), (0.4, 0.0, 0.3)))
    assert edge is not None and edge.shape == (2, 2)
    np.testing.assert_allclose(sorted(edge[:, 1]), (-0.1, 0.5), atol=1e-15)
    np.testing.assert_allclose(edge[:, 0], 0.1, atol=1e-15)


def test_round_shapes_project_to_their_closed_forms() -> None:
    r = 0.05
    capsule = silhouette(Capsule((0.3, -0.2, 0.5), (0.9, 0.2, 0.8), r))  # in view: L = 0.5
    assert capsule is not None
    stadium = 2 * r * 0.5 + math.pi * r**2
    assert _area(capsule) == pytest.approx(stadium, rel=2e-3)
    assert _area(capsule) <= stadium  # inscribed
    along = silhouette(
        Cylinder((0.4, 0.0, 0.3), r, 0.2, rotation_from_rpy((0.0, math.pi / 2, 0.0)))
    )
    assert along is not None  # its axis is x: seen end-on, a disc
    assert _area(along) == pytest.approx(ROUND * math.pi * r**2, rel=1e-12)
    side = silhouette(Cylinder((0.4, 0.0, 0.3), r, 0.2))  # axis z: a 2 r x 2 h rectangle
    assert side is not None and _area(side) == pytest.approx(2 * r * 0.4, rel=1e-12)


def test_draw_obstacles_draws_each_shape_and_counts_the_left_out() -> None:
    _, ax = figure((3, 3))
    shapes = [
        Sphere((0.5, 0.1, 0.2), 0.07),
        Box((0.5, -0.2, 0.3), (0.05, 0.05, 0.05)),
        Capsule((0.4, -0.1, 0.1), (0.4, 0.1, 0.1), 0.02),
        HalfSpace((0.0, 0.0, 1.0), 0.0),  # the floor: a line in the front view
        HalfSpace((1.0, 0.0, 0.0), -0.3),  # a wall behind: fills the front view
    ]
    assert draw_obstacles(ax, shapes) == 1
    circles = [p for p in ax.patches if isinstance(p, Circle)]
    polygons = [p for p in ax.patches if isinstance(p, Polygon)]
    assert len(circles) == 1 and circles[0].center == pytest.approx((0.1, 0.2))
    assert circles[0].radius == 0.07 and len(polygons) == 2
    assert len(ax.lines) == 1  # the floor's boundary, z = 0


def test_a_view_needs_two_different_axes() -> None:
    with pytest.raises(GeosynError, match="axes"):
        silhouette(Box((0, 0, 0), (1, 1, 1)), (1, 1))
