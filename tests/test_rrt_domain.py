"""RRT-Connect's balanced trees and dynamic domain (`geosyn.metrics.planning.rrt`).

Referee: a closed-form 2-D scene, a square room with one narrow door on its far side
and the goal inside. Every path is checked 10x finer than the search's resolution r
against the walls eroded by r / 2: a point of a segment whose checked points are r
apart is within r / 2 of one of them, so it can enter a wall by r / 2 at most."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from geosyn.core.errors import InvalidArgument
from geosyn.metrics.planning.planner import densify
from geosyn.metrics.planning.rrt import DYNAMIC_DOMAIN, rrt_connect

DOOR = 0.02  # [rad] width of the door in the room's right wall (walls 0.02 thick)


RESOLUTION = 0.004  # [rad] the search's edge check


def room_valid(Q: np.ndarray, erode: float = 0.0) -> np.ndarray:
    """(K,) whether each point of Q (K, 2) is outside the walls of the room centred at
    (0.5, 0.5), half side 0.1, door of width `DOOR` in its right wall; the walls eroded
    by ``erode`` on every side."""
    x, y = Q[:, 0] - 0.5, Q[:, 1] - 0.5
    ax, ay = np.abs(x), np.abs(y)
    ring = (np.maximum(ax, ay) > 0.09 + erode) & (np.maximum(ax, ay) < 0.11 - erode)
    door = (x > 0) & (ax > ay) & (ay < DOOR / 2 + erode)
    return ~(ring & ~door)


Q0, Q1 = np.array([0.05, 0.5]), np.array([0.5, 0.5])  # outside, left; the room's centre
LO, HI = np.zeros(2), np.ones(2)
# the domain at this scene's scale (`DYNAMIC_DOMAIN`'s radii are for arms' joint boxes)
SCALED: dict[str, Any] = {"domain": (0.1, 0.03, 1e-4)}


def grow(seed: int, **kwargs: Any) -> tuple[np.ndarray, int]:
    path, nodes = rrt_connect(room_valid, Q0, Q1, LO, HI, step=0.03, resolution=RESOLUTION,
                              budget=60.0, seed=seed, max_nodes=20000, **kwargs)  # fmt: skip
    assert path is not None, f"seed {seed}: no path"
    return path, nodes


def test_balanced_trees_leave_a_narrow_room_with_fewer_nodes() -> None:
    """Over 8 seeds, the balanced search with a dynamic domain at this scene's scale
    grows fewer nodes in median than plain RRT-Connect (measured: 291 against 785);
    every path joins the ends, keeps the step and is valid (module docstring)."""
    plain: list[int] = []
    scaled: list[int] = []
    for seed in range(8):
        for out, kwargs in ((plain, {"domain": None, "balance": False}), (scaled, SCALED)):
            path, nodes = grow(seed, **kwargs)
            np.testing.assert_array_equal(path[[0, -1]], np.stack([Q0, Q1]))
            assert np.all(room_valid(densify(path, 10), erode=RESOLUTION / 2))
            assert np.all(np.linalg.norm(np.diff(path, axis=0), axis=1) <= 0.03 + 1e-12)
            out.append(nodes)
    assert np.median(scaled) < 0.7 * np.median(plain), (plain, scaled)


def test_the_search_is_seeded_with_each_setting() -> None:
    """The same seed gives the same path, by default and with the domain alone."""
    for kwargs in ({}, {"domain": (0.1, 0.03, 0.01), "balance": False}):
        first, _ = grow(3, **kwargs)
        again, _ = grow(3, **kwargs)
        np.testing.assert_array_equal(first, again)


@pytest.mark.parametrize(
    "domain",
    [
        (1.0, 2.0, 1e-4),
        (0.0, 0.0, 0.1),
        (2.0, 0.6, 1.0),
        (np.inf, 0.6, 1e-4),
        (1.0, 0.5),
        "a",
        (True, 0.5, 0.1),  # a boolean is not a radius
    ],
)
def test_a_bad_domain_is_refused_by_name(domain: object) -> None:
    with pytest.raises(InvalidArgument, match="domain"):
        rrt_connect(room_valid, Q0, Q1, LO, HI, domain=domain)  # type: ignore[arg-type]


def test_the_default_domain_is_valid() -> None:
    radius, smallest, alpha = DYNAMIC_DOMAIN
    assert 0.0 < smallest <= radius and 0.0 <= alpha < 1.0
