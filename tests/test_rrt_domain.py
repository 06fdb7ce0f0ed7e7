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


OPENINGS = ((0.3, 0.4), (0.95, 1.0))  # [rad] y ranges open in the wall: near, far
NEAR = (np.array([0.1, 0.3]), np.array([0.9, 0.7]), 0.9)  # y in [0.3, 0.7]: no far sample


def wall_valid(Q: np.ndarray, openings: tuple = OPENINGS, erode: float = 0.0) -> np.ndarray:
    """(K,) whether each point of Q (K, 2) is off the wall x in [0.49, 0.51] of the unit
    box, open where y is within one of ``openings``; the wall eroded by ``erode`` on
    every side (thinner, its openings wider)."""
    x, y = Q[:, 0], Q[:, 1]
    open_ = np.zeros(len(Q), dtype=bool)
    for low, high in openings:
        open_ |= (y > low - erode) & (y < high + erode)
    return ~((np.abs(x - 0.5) < 0.01 - erode) & ~open_)


def wall_path(seed: int, openings: tuple, near: Any) -> np.ndarray:
    """RRT-Connect from (0.3, 0.5) to (0.7, 0.5) through the wall's ``openings``; the
    path checked 10x finer than the search's resolution (module docstring)."""
    q0, q1 = np.array([0.3, 0.5]), np.array([0.7, 0.5])
    path, _ = rrt_connect(lambda Q: wall_valid(Q, openings), q0, q1, LO, HI, step=0.03,
                          resolution=RESOLUTION, budget=60.0, seed=seed, near=near)  # fmt: skip
    assert path is not None, f"seed {seed}: no path"
    np.testing.assert_array_equal(path[[0, -1]], np.stack([q0, q1]))
    assert np.all(wall_valid(densify(path, 10), openings, erode=RESOLUTION / 2))
    return path


def test_samples_near_the_ends_find_the_near_way_round_first() -> None:
    """Two openings in a wall between start (0.3, 0.5) and goal (0.7, 0.5): one next to
    them (y in [0.3, 0.4]: a way of joint length >= 0.45), one far off (y >= 0.95: >=
    1.0). Over 8 seeds, with 0.9 of the samples from the box round the ends (y in [0.3,
    0.7], none near the far opening) every first path goes through the near opening;
    with all samples from the whole box, some go round the far one."""
    far = {False: 0, True: 0}
    for seed in range(8):
        for near in (None, NEAR):
            path = wall_path(seed, OPENINGS, near)
            far[near is not None] += int(path[:, 1].max() > 0.9)
    assert far[True] == 0 and far[False] >= 1, far


def test_a_way_outside_the_near_box_is_still_found_and_the_search_seeded() -> None:
    """The far opening alone: with 0.9 of the samples round the ends, where no way
    lies, the search still connects through it (the rest come from the whole box), and
    the same seed gives the same path."""
    path = wall_path(2, OPENINGS[1:], NEAR)
    assert path[:, 1].max() > 0.95
    np.testing.assert_array_equal(path, wall_path(2, OPENINGS[1:], NEAR))


@pytest.mark.parametrize(
    "near",
    [
        (np.array([0.1, 0.3]), np.array([0.9, 0.7]), 1.5),  # share above 1
        (np.array([-0.1, 0.3]), np.array([0.9, 0.7]), 0.5),  # outside the box
        (np.array([0.9, 0.3]), np.array([0.1, 0.7]), 0.5),  # lower above upper
        (np.array([0.1]), np.array([0.9, 0.7]), 0.5),  # not (n,)
        (0.5,),
    ],
)
def test_a_bad_near_box_is_refused_by_name(near: object) -> None:
    with pytest.raises(InvalidArgument, match="near"):
        rrt_connect(room_valid, Q0, Q1, LO, HI, near=near)  # type: ignore[arg-type]
