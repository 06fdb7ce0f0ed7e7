"""`Plan`: a planned path, how it was found and how it was checked."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from geosyn.metrics.geodesic.collocation import CollocationResult

__all__ = ["Plan"]


class Plan(NamedTuple):
    """A planned path and how it was found.

    Attributes:
        result: the collocation result (path, kind, energy, clearance, ...).
        seed: the global seed of the final collocation: ``"straight line"`` (directly,
            or through a coarse collocation: ``attempts`` says which) or
            ``"rrt-connect"`` (``"rrt-connect #i"`` for the i-th alternative seed),
            ``"sampled"``: RRT-Connect's path on the spheres (or the straight line when
            free on them, or when they gave no connection but the exact geometry passes
            it: `geosyn.metrics.planning.sampled.exact_line`) shortened in the metric,
            no NLP (``result`` of kind
            ``"feasible"``; `geosyn.metrics.planning.query`), or
            ``"anytime"``: the budget ended before any solve converged, and this is the
            lowest-energy interrupted iterate or seed that passed every check (``result``
            of kind ``"feasible"``).
        check_clearance: smallest clearance [m] on the path checked ``check_factor``
            times finer than its samples (linear in between), by the constraints' smooth
            minimum (at most ``log(n_spheres) / softmin`` below the exact one; for a
            ``"sampled"`` plan the exact sphere distances).
        wall_time: wall-clock time of the query [s].
        attempts: one line per method tried.
        fine_clearance: the same, checked at most ``check_step`` apart in joint space
            (NaN for a ``"sampled"`` plan of a robot with file geometry: the exact
            check decides).
        exact_clearance: smallest signed distance [m] between the robot's own collision
            geometry (its file's meshes and primitives, `geosyn.world.exact_clearance`)
            and the obstacles along the path, linear between samples, checked at most
            ``exact_resolution`` apart (joint max-norm); a mesh is measured on its convex
            hull, which contains it, or bounded by the fitted spheres that cover it
            (`geosyn.metrics.planning.exact_path.PathAids`): at most the meshes' own
            clearance. Never negative for a returned plan; NaN when the robot has no file
            geometry (``attempts`` says so).
        exact_resolution: that joint-space resolution [rad].
        first_feasible_time: when the query's first plan passing every check was found,
            from the query's start [s].
        nlp_build_time: time spent before the query's clock started building the NLPs
            of its obstacle slot count (its first query with that count; else 0) [s].
        self_clearance: smallest exact distance [m] between the file's self-collision
            link pairs along the path, at the configurations ``exact_resolution`` apart
            (`geosyn.metrics.planning.self_path.path_self_contact`: the sphere
            bounds everywhere, coal where they are closest); never negative for a
            returned plan (a self-colliding path is refused); at most `SELF_NEAR`
            (0.02 m: "at least" that); a lower bound of it when its refinement was cut
            short (`SELF_REFINE_TIME` after the path was decided self-clear); NaN when
            the robot has no file geometry.
        certified_clearance: a lower bound [m] of ``exact_clearance`` between the checked
            configurations too (`geosyn.metrics.planning.certify`), with
            ``Planner.plan(..., certify=True)``; NaN otherwise or without file geometry.
    """

    result: CollocationResult
    seed: str
    check_clearance: float
    wall_time: float
    attempts: tuple[str, ...]
    fine_clearance: float = math.nan
    exact_clearance: float = math.nan
    exact_resolution: float = math.nan
    first_feasible_time: float = math.nan
    nlp_build_time: float = 0.0
    self_clearance: float = math.nan
    certified_clearance: float = math.nan

    @property
    def q(self) -> np.ndarray:
        """(T, n) the path [rad]."""
        return self.result.q
