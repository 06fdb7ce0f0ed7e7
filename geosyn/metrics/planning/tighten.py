"""`exact_tighten`: a sampled plan's path pulled nearer the obstacles on the robot's own
collision geometry, where the covering spheres keep it farther than it needs to be.

The planner's spheres cover every mesh point with up to 2 cm to spare
(`geosyn.robots.collision_spheres`), so a path tightened on them
(`geosyn.metrics.planning.sampled.pull_taut`) keeps 1.5-3 cm of exact clearance on the
Panda scenes where the margin asks for 1 cm. This last stage relaxes the path once more
(`geosyn.metrics.planning.relax.metric_relax`) with the clearance of every sample taken
exactly (coal, `geosyn.metrics.planning.exact_path.configuration_clearances`; their
gradients from coal's witness points and Pinocchio's joint Jacobians,
`~geosyn.metrics.planning.exact_path.configuration_gradients`; the penalty acts below
the planner's margin) and only steps whose whole path keeps at least
`EXACT_FLOOR` times the margin at every configuration of the exact check
(`geosyn.metrics.planning.exact_path.path_clearance`, the verification's own
resolution), within the joint limits. Self-collision is left to the verification that
follows, as for every plan.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from geosyn.metrics.planning.exact_path import (
    configuration_clearances,
    configuration_gradients,
    path_clearance,
)
from geosyn.metrics.planning.relax import metric_relax
from geosyn.metrics.planning.smoothing import even_in_metric

if TYPE_CHECKING:
    from geosyn.metrics.planning.planner import Planner

__all__ = [
    "EXACT_FD_STEP",
    "EXACT_FLOOR",
    "EXACT_KEEP",
    "EXACT_MIN_TIME",
    "PUSH_DELTA",
    "PUSH_SHARE",
    "exact_movable",
    "exact_push",
    "exact_tighten",
]

EXACT_FLOOR = 0.5
"""Share of the planner's margin that every configuration of the exact check keeps
(exact clearance) throughout the tightening."""

EXACT_MIN_TIME = 0.01
"""Least time [s] left of a query (beyond its final checks) for which a sampled plan is
tightened. On the Panda scenes it converged in 10-35 ms (40-220 ms on a machine 2.8x
slower), a step 3-10 ms; a step that would end past the budget is not begun, and the
checks' reserve comes on top; a query also waits for twice its last exact check's time
(the set-up and first step cost 1-4 such checks, measured; on a slower machine they
grow alike). 0.02 left it out of most 0.1 s queries; at 0.01 it
shortened their plans on 8 of the 14 scenes (by up to 3.9 %, table_box) and every
0.05-0.2 s query kept its budget (wall <= 0.94 T, measured)."""

EXACT_KEEP = 0.1
"""Time [s] a sampled plan's polishing keeps back for its tightening when more than
twice that is left (other RRT-Connect paths are not tried in it; with less, the
polishing relaxes on the spheres first and the tightening gets what is left beyond
`EXACT_MIN_TIME`): on the Panda scenes tightening shortened the kept path by
1-4 %, a new RRT-Connect path in the last 0.1 s seldom did (measured)."""

PUSH_SHARE = 0.85
"""Share of `exact_push`'s budget that pushing the path out may take; it stops at the
first iterate that keeps the floor, and the tightening has the rest. It took 0.6 and went
on lowering the energy under the push-out's penalty after that iterate: on the Panda
scenes a 0.16 s query's thinner path (slot) was then not brought out in its 44 ms, where
59 ms did (measured); pushing stops early instead, and the tightening lowers it more."""

PUSH_DELTA = 2.0
"""Clearance below which `exact_push` penalises a sample, in margins (it pushes the path
out past the floor, so that the tightening then has a valid start)."""

EXACT_FD_STEP = 1e-4
"""Central-difference step [rad] of the exact clearances' gradients where they are not
taken from coal's witness points (`configuration_gradients`: a robot with ``nq != nv``;
coal's distances, GJK to 1e-9 m: 1e-5 relative error in the gradient)."""


class _ExactTerms(NamedTuple):
    """What a relaxation on the exact geometry asks, for the query set on a planner."""

    floor: float  # [m] every configuration of the exact check keeps this
    # (K, n), cap [m] -> (K,) exact clearances [m] (at most the cap), (K, n) theirs [m/rad]
    clearances: Callable[[np.ndarray, float], np.ndarray]
    gradients: Callable[[np.ndarray, float], np.ndarray] | None
    path_ok: Callable[[np.ndarray], bool]  # a whole path (T, n) keeps the floor


def exact_movable(planner: Planner) -> bool:
    """Whether ``planner``'s paths can be moved on the exact geometry (`exact_tighten`,
    `exact_push`): it has file geometry, a margin (whose floor they keep) and its own
    spheres fitted to that geometry (spheres the user gives must keep clear as well, and
    may stand beyond it, a held object: paths moved nearer the meshes would cross them)."""
    return planner.exact is not None and planner.margin > 0.0 and not planner.given_spheres


def _exact_terms(planner: Planner) -> _ExactTerms | None:
    """The exact terms of ``planner``'s query (its obstacles set on the exact checker), or
    None when not `exact_movable`."""
    exact, aids = planner.exact, planner.sampling.aids
    if exact is None or not exact_movable(planner):
        return None
    floor = EXACT_FLOOR * planner.margin
    exact.set_obstacles(planner.term.obstacles)

    def clearances(Q: np.ndarray, cap: float) -> np.ndarray:
        return configuration_clearances(exact, Q, aids, cap)

    def gradients(Q: np.ndarray, cap: float) -> np.ndarray:
        return configuration_gradients(exact, Q, aids, cap)[1]

    def path_ok(x: np.ndarray) -> bool:  # capped at the floor: only the pairs below it
        check = path_clearance(exact, x, planner.exact_resolution, aids=aids, cap=floor)
        return bool(check.clearance >= floor)

    model = planner.robot.model  # nq != nv: central differences (`EXACT_FD_STEP`)
    return _ExactTerms(floor, clearances, gradients if model.nq == model.nv else None, path_ok)


def _relax(planner: Planner, terms: _ExactTerms, path: np.ndarray, budget: float,
           delta: float, valid: bool) -> np.ndarray:  # fmt: skip
    """`metric_relax` of ``path`` on the exact terms within the joint limits: tightening
    (``valid``: every step keeps the floor) or pushing out (until the first iterate that
    keeps it). The clearances are capped at ``delta`` (above it the penalty is zero:
    fewer pairs measured, the same steps)."""
    grads = terms.gradients
    return metric_relax(
        None, lambda Q: terms.clearances(Q, delta), planner.metric, path, budget=budget,
        delta=delta, stay_valid=valid, seed_valid=valid, path_ok=terms.path_ok,
        fd_step=EXACT_FD_STEP, floor=terms.floor,
        gradients=None if grads is None else lambda Q: grads(Q, delta),
        bounds=(planner.robot.q_min, planner.robot.q_max), first_valid=not valid,
    )  # fmt: skip


def exact_tighten(planner: Planner, path: np.ndarray, budget: float) -> np.ndarray:
    """``path`` (T, n) [rad] (valid for the query set on ``planner``: its obstacles on
    the exact checker and the sampling aids) relaxed on the exact clearances within
    ``budget`` [s] (module docstring); ``path`` itself when the planner has no exact
    geometry, no margin, or no step keeps the floor.

    Each step costs about 2 T exact clearances (the samples' values and gradients) plus
    an exact check of the path per trial (3-20 ms on the Panda scenes).
    """
    terms = _exact_terms(planner)
    if terms is None or budget <= 0.0 or not terms.path_ok(path):
        return np.asarray(path, dtype=float)  # e.g. nearer on the spheres: nothing to keep
    return _relax(planner, terms, path, budget, planner.margin, valid=True)


def exact_push(planner: Planner, path: np.ndarray, budget: float) -> np.ndarray | None:
    """``path`` (T, n) [rad], which may cross the query's obstacles, as ``nodes + 1``
    samples even in the metric, pushed out of them on the exact clearances (penalty below
    `PUSH_DELTA` times the margin, in `PUSH_SHARE` of ``budget``, until the first iterate
    that keeps the floor at every configuration of the exact check) and tightened
    (`exact_tighten`) in the rest of ``budget`` [s]: (nodes + 1, n) [rad], or None (not
    brought out in time, or no exact geometry)."""
    terms = _exact_terms(planner)
    if terms is None or budget <= 0.0:
        return None
    end = time.perf_counter() + budget
    x = even_in_metric(planner.metric, path, planner.nodes + 1)
    x[0], x[-1] = path[0], path[-1]
    if not terms.path_ok(x):
        x = _relax(planner, terms, x, PUSH_SHARE * budget, PUSH_DELTA * planner.margin, valid=False)
        if not terms.path_ok(x):
            return None
    return _relax(planner, terms, x, max(end - time.perf_counter(), 0.0), planner.margin, True)
