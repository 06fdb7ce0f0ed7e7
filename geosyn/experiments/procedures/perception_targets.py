"""The targets of `perception_reach`: where they go, why a target's run failed, and
how the synergy map alone and `reach` alone do on them."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from geosyn.metrics.planning.verify import outside_limits
from geosyn.robots import Robot
from geosyn.synergies import ReachOutsideLimits, reach
from geosyn.synergies.perception_map import SynergyMap

__all__ = ["ROWS", "map_vs_reach", "target_failures", "target_paths"]


def target_paths(smap: SynergyMap, p: Any, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """((N, 3) final target positions [m], (N, 3) start offsets [m]), seeded."""
    finals, _ = smap.sample(p.n_targets, p.target_scale * p.weight_scale, seed + 1)
    rng = np.random.default_rng(seed + 2)
    d = rng.normal(size=(p.n_targets, 3))
    d *= p.drift / np.linalg.norm(d, axis=1, keepdims=True)
    return finals, d


ROWS = ("final_error", "perception_error", "replans", "refined", "misses", "ok")


def target_failures(robot: Robot, q_ref: np.ndarray, final_error: float, p: Any) -> list[str]:
    """Why a target's run failed beyond the simulation's own status (none: it did not).

    Args:
        robot: the robot (its joint position limits).
        q_ref: (T, n) the reference the controller tracked [rad], one row per tick.
        final_error: distance of the hand from the true final target at the end [m].
        p: the parameters (``success_radius`` [m]).
    """
    out = []
    if not final_error <= p.success_radius:
        out.append(
            f"missed the target: the hand ends {final_error * 1e3:.4g} mm from it"
            f" (success radius {p.success_radius * 1e3:.4g} mm)"
        )
    why = outside_limits(robot, q_ref)  # the planner's own check and tolerance
    if why:
        out.append(f"the reference leaves the joint limits: {why}")
    return out


def map_vs_reach(
    smap: SynergyMap, syns: list[Any], targets: np.ndarray, frame: str, robot: Robot, p: Any
) -> dict[str, np.ndarray]:
    """Error and time of the map's weights (unrefined) and of `reach` alone per target."""
    map_err, map_t, reach_err, reach_t = [], [], [], []
    for pt in targets:
        c0 = time.perf_counter()
        w = smap.weights(pt)
        map_t.append(time.perf_counter() - c0)
        map_err.append(float(np.linalg.norm(smap.endpoint(w) - pt)))
        c0 = time.perf_counter()
        try:
            reach_err.append(reach(syns, pt, frame, robot, steps=p.steps, restarts=2).error)
        except ReachOutsideLimits:  # counted in the summary (reach_outside_limits)
            reach_err.append(float("nan"))
        reach_t.append(time.perf_counter() - c0)
    return {
        "map_error": np.array(map_err),
        "map_time": np.array(map_t),
        "reach_error": np.array(reach_err),
        "reach_time": np.array(reach_t),
    }
