"""`path_self_contact`: the exact self-clearance of a path, on a `SelfCollision`.

Rule for plans: a path is checked at the configurations of
`geosyn.metrics.planning.exact_path.checked_configurations` (the exact check's
resolution); at each, every pair's sphere distance (`SphereCheck.self_clearances`: a
lower bound of the exact one) is computed. The (configuration, pair) items whose bound is
below `SELF_NEAR` are then refined best first, the lowest bound first, until the next
bound is not below the smallest exact distance found (or that distance is negative: the
plan is then refused or repaired, never returned): an item with a sphere bound gets its
convex hulls' coal distance (`SelfCollision.placed_bound`: exact for convex shapes, a
lower bound for a URDF mesh, which its hull contains) and goes back in line with it; a
mesh item with a hull bound below `SELF_APART` gets coal's collision test of its
triangles with that security margin (`SelfCollision.placed_apart`, ~1/15 of their
distance's cost): apart, it goes back in line at `SELF_APART`; a mesh item with any other
bound gets coal's distance between the triangles; and an item whose
pair was measured at configurations nearby gets the bound those give, less the most the
pair can have moved since (conservative advancement, `SelfCollision.pair_weights`), and
goes back in line with it. The result is the same exact minimum as refining every item;
the triangles are measured only where the hulls do not already decide (a pair the path
keeps a few centimetres apart is then measured on its hulls, 4-9 us, instead of its
triangles, 100-350 us, on the UR5), and their distance only where they are nearer than
`SELF_APART` or once the path is decided.

Lowest bound first, every item that could intersect is refined before any that cannot:
once the next bound is not negative the path is decided (self-clear). Refining on for the
exact minimum is then bounded by `SELF_REFINE_TIME`; cut short, the result is the
smallest bound left (a lower bound of the exact minimum, not negative). On the SO-101
(meshes of 17,000-54,000 triangles, a pair 9 mm apart along a 1,429-configuration line)
the exact minimum took 6.7 s and ran the 2 s query out of time.
"""

from __future__ import annotations

import bisect
import heapq
import math
import time
from itertools import repeat
from typing import NamedTuple

import numpy as np

from geosyn.metrics.planning.exact_path import Kinematics, checked_configurations
from geosyn.metrics.planning.self_collision import Placements, SelfCollision
from geosyn.metrics.planning.sphere_check import SphereCheck

__all__ = [
    "SELF_APART",
    "SELF_NEAR",
    "SELF_REFINE_TIME",
    "SelfContact",
    "path_self_contact",
]

SELF_NEAR = 0.02
"""Self-clearance [m] beyond which the sphere bound is not refined: a plan whose pairs'
sphere distances all exceed it reports this value ("at least")."""

SELF_APART = 0.002
"""Margin [m] of `SelfCollision.placed_apart`: a mesh item whose hulls' bound is below it
is first tested for its triangles being more than this apart (coal's collision test,
0.03 ms an item on the UR5 against 0.33 ms for their distance, measured); only a pair
nearer than that is measured. The path is decided on these tests, and its exact minimum
is found when below this margin."""

SELF_REFINE_TIME = 0.05
"""Most time [s] `path_self_contact` refines a decided path towards its exact minimum
(module docstring)."""


class SelfContact(NamedTuple):
    """Where a path self-collides (`path_self_contact`): at the checked configuration
    ``q`` (n,) [rad], the links of self pair ``pair`` (an index of the spheres'
    ``self_pairs``) intersect."""

    q: np.ndarray
    pair: int


def path_self_contact(
    checker: SelfCollision | None,
    spheres: SphereCheck,
    path: np.ndarray,
    resolution: float,
    deadline: float = math.inf,
    kinematics: Kinematics | None = None,
) -> tuple[float, SelfContact | None]:
    """Smallest exact self-clearance [m] of the linear interpolation of ``path`` (T, n)
    [rad] at most ``resolution`` [rad] apart (the module's rule; ``spheres`` has the same
    pairs set, `SphereCheck.set_self_pairs`).

    Returns ``(clearance, contact)``. The clearance: the exact minimum when it is below
    `SELF_NEAR` and not negative, else `SELF_NEAR` ("at least"); a lower bound of it,
    not negative, when the path was decided self-clear and refining it took more than
    `SELF_REFINE_TIME` or passed ``deadline`` [s]; a negative value (some exact
    penetration, not necessarily the deepest) when the path self-collides; NaN without
    ``checker`` or when ``time.perf_counter()`` passes ``deadline`` before the path is
    decided. The clock is read before every item; a triangle item is not begun when the
    slowest one so far would end past the deadline (or `SELF_REFINE_TIME`). An item
    whose pair was measured at nearby configurations goes back in line with the bound
    those give (`SelfCollision.pair_weights`: conservative advancement); the same
    result, fewer items measured. The contact:
    where that penetration was found when negative, else None.
    ``kinematics``: the joints' placements of every checked configuration at once (e.g.
    in C): the same result without one Pinocchio call per measured item.
    """
    if checker is None:
        return math.nan, None
    Q = checked_configurations(path, resolution)
    bound = spheres.self_clearances(Q)  # (K, P)
    near = np.flatnonzero(bound.ravel() < SELF_NEAR)
    # (bound, stage, hint, item); stage 0: the spheres' bound, 1: the hulls', 2: the
    # triangles more than `SELF_APART` apart (hint: the hulls' bound, nearest first)
    line = list(zip(bound.ravel()[near].tolist(), repeat(0), repeat(0.0), near.tolist()))
    if not line:  # every pair at least `SELF_NEAR` apart on the spheres
        return SELF_NEAR, None
    heapq.heapify(line)
    low, slowest = SELF_NEAR, 0.0  # slowest: the longest triangle item so far [s]
    frames: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    placed: dict[int, Placements] = {}  # the objects' coal placements, per configuration
    if kinematics is not None:  # the configurations with an item to measure
        at = np.unique(near // bound.shape[1])
        R, p = kinematics(Q[at])
        frames = {int(i): (R[r], p[r]) for r, i in enumerate(at)}
    refine_end = math.inf  # set once decided: every item left is apart
    advance = _Advance(checker, spheres.self_pairs, Q)
    while line and line[0][0] < low:  # every item left is at least ``low`` apart
        if math.isinf(refine_end) and line[0][0] >= 0.0:
            refine_end = time.perf_counter() + SELF_REFINE_TIME
        value, stage, hint, index = heapq.heappop(line)
        i, k = divmod(index, bound.shape[1])  # (configuration, pair)
        if (known := advance.bound(i, k)) > value:  # a bound from the pair's measured items
            heapq.heappush(line, (known, stage, hint, index))
            continue
        # the clock before every item (4 us for two hulls, up to 7 ms for two fine meshes'
        # triangles on the SO-101): a triangle item only when the slowest so far still fits
        if time.perf_counter() + (slowest if stage else 0.0) > min(deadline, refine_end):
            return (min(low, value) if value >= 0.0 else math.nan), None  # lowest first
        if i not in placed:
            placed[i] = checker.placements(*(frames.get(i) or checker.joint_frames(Q[i])))
        pair = spheres.self_pairs[k]
        if not stage:
            d, exact = checker.placed_bound(placed[i], pair)
            advance.record(i, k, max(d, value))
            if not exact:  # back in line with the tighter bound
                heapq.heappush(line, (max(d, value), 1, 0.0, index))
                continue
        else:
            start = time.perf_counter()
            if stage == 1 and value < SELF_APART and checker.placed_apart(placed[i], pair,
                                                                          SELF_APART):  # fmt: skip
                slowest = max(slowest, time.perf_counter() - start)
                advance.record(i, k, SELF_APART)
                heapq.heappush(line, (SELF_APART, 2, value, index))
                continue
            d = checker.placed_clearance(placed[i], pair)
            slowest = max(slowest, time.perf_counter() - start)
            advance.record(i, k, d)
        low = min(low, d)
        if low < 0.0:
            return low, SelfContact(Q[i].copy(), k)
    return low, None


class _Advance:
    """Conservative advancement of a path's self check (`path_self_contact`), per pair: a
    lower bound ``d`` of a pair's distance measured at checked configuration ``i`` holds
    at any other ``m``, less the most the pair can have moved along the path between them,
    ``|C[m] - C[i]|``, ``C`` the cumulative sum of ``sum_j w[j] |dq_j|`` over the path's
    steps (`SelfCollision.pair_weights`; the same rule as
    `geosyn.metrics.planning.certify`). An item whose bound from its pair's nearest
    measured items on each side is above its own goes back in line with it: an item
    near one measured a few milliradians away is seldom measured."""

    def __init__(self, checker: SelfCollision, pairs: tuple[tuple[str, str], ...],
                 Q: np.ndarray) -> None:  # fmt: skip
        """``Q`` (K, n): the path's checked configurations [rad]."""
        weights = [checker.pair_weights(pair) for pair in pairs]
        steps = np.abs(np.diff(Q, axis=0))  # (K - 1, n)
        C = np.zeros((len(pairs), len(Q)))  # per pair, its cumulative motion bound [m]
        for k, w in enumerate(weights):
            if w is not None:
                C[k, 1:] = np.cumsum(steps @ w)
        self.C: list[list[float]] = C.tolist()  # Python floats: read per item
        self.bounded = [w is not None for w in weights]
        self.at: list[list[int]] = [[] for _ in pairs]  # measured configurations, sorted
        self.low: list[dict[int, float]] = [{} for _ in pairs]  # their bounds [m]

    def bound(self, i: int, k: int) -> float:
        """Lower bound [m] of pair ``k``'s distance at configuration ``i`` from its nearest
        measured configurations on either side (-inf: none, or no weights)."""
        at, best = self.at[k], -math.inf
        if not at or not self.bounded[k]:
            return best
        C, low = self.C[k], self.low[k]
        j = bisect.bisect_left(at, i)
        for m in at[max(j - 1, 0) : j + 2]:
            if m != i:
                best = max(best, low[m] - abs(C[i] - C[m]))
        return best

    def record(self, i: int, k: int, d: float) -> None:
        """Pair ``k``'s distance at configuration ``i`` is at least ``d`` [m]."""
        low = self.low[k]
        if i not in low:
            bisect.insort(self.at[k], i)
            low[i] = d
        else:
            low[i] = max(d, low[i])
