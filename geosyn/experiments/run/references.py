"""The references of a config: every ``reference`` section type becomes a library
reference (`geosyn.controllers.reference`) here and nowhere else.

``combination`` and ``log`` sections give a geodesic (`reference_geodesic`) tracked as a
`GeodesicReference` (`tracked_reference`); ``goals`` a `SequenceReference` of geodesics
through the goals (`goals_reference`); ``planned`` the planner's collision-free path
around the scene's obstacles (`planned_reference`).

On a robot with coupled joints (``robot.coupling``, ``q = S z + c``), every reference is
computed in the independent coordinates z on the pull-back metric
`CoupledMetric(metric, coupling)` and lifted to the joints by `CoupledReference`, so it
stays on the coupling to rounding: its start and goals must satisfy the coupling (to
`COUPLING_TOLERANCE`, else `ProcedureFailed` names the configuration and its residual); a
combination's velocity is the metric-orthogonal projection of the synergies' velocity onto
the coupling's tangent space (the dropped part is warned about); a ``planned`` reference is
refused (the planner plans in the joints and cannot keep the coupling).
`reference_coupling_residual` gives a reference's own constraint residual for the summaries.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from geosyn.controllers import GeodesicReference
from geosyn.controllers.coupled_reference import CoupledReference
from geosyn.controllers.reference import Reference
from geosyn.controllers.sequence_reference import SequenceReference
from geosyn.experiments import schema as S
from geosyn.experiments.errors import ProcedureFailed
from geosyn.metrics import CoupledMetric, Metric
from geosyn.metrics.geodesic import Geodesic, exp, log
from geosyn.metrics.planning import Plan, Planner
from geosyn.robots import Coupling
from geosyn.robots.errors import RobotWarning
from geosyn.synergies import GeodesicSynergy, combine
from geosyn.world import Shape

COUPLING_TOLERANCE = 1e-6
"""Largest constraint residual [rad or m] of a coupled robot's reference start or goal: a
configuration within it is moved onto the coupling (``S z + c`` of its independent joints),
one beyond it is refused."""

TrackedReference = GeodesicReference | CoupledReference


def reference_coupling(metric: Metric) -> Coupling | None:
    """The coupling that a reference on ``metric`` must keep: the robot's ``coupling`` when
    ``metric`` is on its joints (None when uncoupled or already in the independent
    coordinates, e.g. a `CoupledMetric`)."""
    coupling = getattr(getattr(metric, "robot", None), "coupling", None)
    if not isinstance(coupling, Coupling) or metric.n != coupling.S.shape[0]:
        return None
    return coupling


def _z_of(coupling: Coupling, q: Sequence[float] | np.ndarray, name: str) -> np.ndarray:
    """(nz,) independent coordinates of ``q``, refused when ``q`` is off the coupling."""
    q_arr = np.asarray(q, dtype=np.float64)
    residual = coupling.residual(q_arr)
    if not residual <= COUPLING_TOLERANCE:
        raise ProcedureFailed(
            f"reference {name} {np.round(q_arr, 6).tolist()} is off the robot's joint coupling"
            f" q = S z + c by {residual:.3g} (allowed {COUPLING_TOLERANCE:g}; constraints:"
            f" {'; '.join(coupling.constraints)}); give a configuration that satisfies them"
        )
    return coupling.z(q_arr)


def _indices(coupling: Coupling) -> list[int]:
    return [coupling.joint_names.index(name) for name in coupling.independent]


def _lift(geo_z: Geodesic, coupling: Coupling) -> Geodesic:
    S, c = np.asarray(coupling.S), np.asarray(coupling.c)
    return Geodesic(geo_z.t, geo_z.q @ S.T + c, geo_z.v @ S.T)


def _z_geodesic(
    metric: Metric, coupling: Coupling, z0: np.ndarray, z1: np.ndarray, duration: float, steps: int
) -> Geodesic:
    cm = CoupledMetric(metric, coupling)
    zd0 = log(cm, z0, z1, steps=steps) / duration
    return exp(cm, z0, zd0, duration, steps)


def _tangent_velocity(
    metric: Metric, coupling: Coupling, q0: np.ndarray, v0: np.ndarray
) -> np.ndarray:
    """(nz,) the metric-orthogonal projection of ``v0`` (nq,) onto the coupling's tangent
    space, ``(S^T G S)^-1 S^T G v0``; warns when it drops more than 1e-9 of ``|v0|``."""
    S = np.asarray(coupling.S, dtype=np.float64)
    G = np.asarray(metric.G(q0), dtype=np.float64)
    zd = np.linalg.solve(S.T @ G @ S, S.T @ G @ v0)
    dropped = float(np.linalg.norm(v0 - S @ zd))
    if dropped > 1e-9 * max(1.0, float(np.linalg.norm(v0))):
        warnings.warn(
            f"the combination's velocity leaves the joint coupling by {dropped:.3g} rad/s;"
            " its projection onto the coupling (in the metric) is tracked",
            RobotWarning,
            stacklevel=3,
        )
    return zd


def reference_geodesic(
    ref: S.ReferenceConfig, metric: Metric, synergies: Sequence[GeodesicSynergy]
) -> Geodesic:
    """The geodesic of a reference section over ``ref.duration`` (before time scaling), in
    the joints (on a coupled robot: computed in z on the pull-back metric, then lifted)."""
    if ref.type in ("goals", "planned", "stance_synergy"):
        raise ProcedureFailed(f"a {ref.type!r} reference is built by kind tracking")
    coupling = reference_coupling(metric)
    if ref.type == "combination":
        q_start = None if ref.q_start is None else np.array(ref.q_start)
        syn = combine(list(synergies), ref.weights, q_start)
        if coupling is None:
            return syn.trajectory(ref.duration, ref.steps)
        q0 = np.asarray(syn.q0, dtype=np.float64)
        z0 = _z_of(coupling, q0, "q_start")
        zd0 = _tangent_velocity(metric, coupling, coupling.q(z0), np.asarray(syn.v0))
        cm = CoupledMetric(metric, coupling)
        return _lift(exp(cm, z0, zd0, ref.duration, ref.steps), coupling)
    if not isinstance(ref, S.LogReference):  # stance_synergy: geosyn.experiments.run.floating
        raise ProcedureFailed(f"a {ref.type!r} reference is built by kind tracking")
    if coupling is not None:
        z0 = _z_of(coupling, ref.q_start, "q_start")
        z1 = _z_of(coupling, ref.goal, "goal")
        return _lift(_z_geodesic(metric, coupling, z0, z1, ref.duration, ref.steps), coupling)
    v0 = log(metric, np.array(ref.q_start), np.array(ref.goal), steps=ref.steps) / ref.duration
    return exp(metric, np.array(ref.q_start), v0, ref.duration, ref.steps)


def build_reference(
    cfg: S.ExperimentConfig, metric: Metric, synergies: Sequence[GeodesicSynergy]
) -> tuple[TrackedReference, Geodesic]:
    """(the tracked reference, its geodesic) of the config's reference section."""
    if cfg.reference is None:
        raise ProcedureFailed(f"experiment {cfg.name!r} has no reference section")
    if isinstance(cfg.reference, S.StanceSynergyReferenceConfig):
        raise ProcedureFailed("a 'stance_synergy' reference is built by kind tracking")
    geo = reference_geodesic(cfg.reference, metric, synergies)
    ref = tracked_reference(geo, metric, cfg.reference.time_scale, cfg.reference.rest_to_rest)
    return ref, geo


def tracked_reference(
    geo: Geodesic, metric: Metric, time_scale: float = 1.0, rest_to_rest: bool = False
) -> TrackedReference:
    """The reference a controller tracks along ``geo`` (``rest_to_rest``: the quintic
    rest-to-rest time law of `GeodesicReference`).

    Accelerations are the metric's exact geodesic accelerations at the samples, interpolated
    between them: a shaped metric's exact geodesic acceleration is too costly to evaluate at
    every control tick.

    On a coupled robot ``geo`` (in the joints) must lie on the coupling (else
    `ProcedureFailed`); it is tracked as its independent coordinates' geodesic of the
    pull-back metric, lifted (`CoupledReference`).
    """
    coupling = reference_coupling(metric)
    if coupling is None:
        return GeodesicReference(
            geo, metric, time_scale=time_scale, rest_to_rest=rest_to_rest, exact_acceleration=False
        )
    q = np.asarray(geo.q, dtype=np.float64)
    residual = max(coupling.residual(qk) for qk in q)
    if not residual <= COUPLING_TOLERANCE:
        raise ProcedureFailed(
            f"the geodesic to track leaves the robot's joint coupling by {residual:.3g}"
            f" (allowed {COUPLING_TOLERANCE:g}): compute it in the independent coordinates"
            " on CoupledMetric(metric, robot.coupling)"
        )
    idx = _indices(coupling)
    geo_z = Geodesic(geo.t, q[:, idx], np.asarray(geo.v, dtype=np.float64)[:, idx])
    inner = GeodesicReference(
        geo_z,
        CoupledMetric(metric, coupling),
        time_scale=time_scale,
        rest_to_rest=rest_to_rest,
        exact_acceleration=False,
    )
    return CoupledReference(inner, coupling)


def goals_reference(ref: S.GoalsReference, metric: Metric) -> tuple[SequenceReference, np.ndarray]:
    """The geodesics from ``q_start`` through every goal, as one reference.

    On a coupled robot each segment is a geodesic of the pull-back metric in z, lifted.

    Returns:
        (the reference, (K, n) the planned configurations at the segment ends [rad]).
    """
    coupling = reference_coupling(metric)
    if coupling is not None:
        return _coupled_goals(ref, metric, coupling)
    q = np.array(ref.q_start, dtype=np.float64)
    t0 = 0.0
    segments: list[Reference] = []
    ends = []
    for goal, duration in zip(ref.goals, ref.durations(), strict=True):
        q1 = np.array(goal, dtype=np.float64)
        v0 = log(metric, q, q1, steps=ref.steps) / duration
        geo = exp(metric, q, v0, duration, ref.steps)
        seg = GeodesicReference(
            geo,
            metric,
            t0=t0,
            time_scale=ref.time_scale,
            rest_to_rest=ref.rest_to_rest,
            exact_acceleration=False,
        )
        segments.append(seg)
        t0 += seg.duration
        q = geo.q[-1].copy()
        ends.append(q)
    return SequenceReference(segments), np.array(ends)


def _coupled_goals(
    ref: S.GoalsReference, metric: Metric, coupling: Coupling
) -> tuple[SequenceReference, np.ndarray]:
    cm = CoupledMetric(metric, coupling)
    z = _z_of(coupling, ref.q_start, "q_start")
    t0 = 0.0
    segments: list[Reference] = []
    ends = []
    for i, (goal, duration) in enumerate(zip(ref.goals, ref.durations(), strict=True)):
        z1 = _z_of(coupling, goal, f"goals[{i}]")
        geo = _z_geodesic(metric, coupling, z, z1, duration, ref.steps)
        inner = GeodesicReference(
            geo,
            cm,
            t0=t0,
            time_scale=ref.time_scale,
            rest_to_rest=ref.rest_to_rest,
            exact_acceleration=False,
        )
        segments.append(CoupledReference(inner, coupling))
        t0 += inner.duration
        z = geo.q[-1].copy()
        ends.append(coupling.q(z))
    return SequenceReference(segments), np.array(ends)


def reference_coupling_residual(reference: Reference, metric: Metric, samples: int = 200) -> float:
    """The reference's own constraint residual, ``max_t |q_ref(t) - (S z + c)|`` [rad or m]
    over ``samples`` uniform times of its moving part and its ends (NaN on an uncoupled
    robot): what part of a tracking error the reference itself puts off the coupling."""
    coupling = reference_coupling(metric)
    if coupling is None:
        return float("nan")
    times = reference.t0 + np.linspace(0.0, reference.duration, max(2, int(samples)))
    return max(coupling.residual(reference.sample(float(t)).q) for t in times)


class _Samples(NamedTuple):
    t: np.ndarray  # (T,) [s]
    q: np.ndarray  # (T, n) [rad]
    v: np.ndarray  # (T, n) [rad/s]


def planned_reference(
    ref: S.PlannedReference, metric: Metric, obstacles: Sequence[Shape], seed: int
) -> tuple[GeodesicReference, Plan]:
    """The planner's collision-free path from ``ref.q_start`` to ``ref.goal`` as a reference.

    The plan is certified between its checked configurations (``plan.certified_clearance``;
    refused when found colliding there). The path's samples, uniform in the planner's
    time, are stretched over ``ref.duration``
    [s]; velocities are their central differences (one-sided at the ends), interpolated
    by cubic Hermite splines; ``time_scale`` and ``rest_to_rest`` act as for a geodesic.

    Raises:
        PlanningError: start or goal outside the limits or in collision, or no path.
        ProcedureFailed: the robot's joints are coupled (the planner plans in the joints
            and cannot keep the coupling).
    """
    coupling = reference_coupling(metric)
    if coupling is not None:
        raise ProcedureFailed(
            "a 'planned' reference is refused on a robot with coupled joints"
            f" ({'; '.join(coupling.constraints)}): the planner samples and shortcuts in the"
            " joints and its path leaves q = S z + c; use a 'log' or 'goals' reference"
        )
    count = max(1, len(obstacles))
    planner = Planner(metric, capacity=count, margin=ref.margin, nodes=ref.nodes, prebuild=count)
    plan = planner.plan(np.array(ref.q_start), ref.planner_goal(), obstacles,
                        budget=ref.budget, seed=seed, certify=True)  # fmt: skip
    t = np.asarray(plan.result.t, dtype=np.float64)
    t = (t - t[0]) * (ref.duration / (t[-1] - t[0]))
    q = np.asarray(plan.q, dtype=np.float64)
    samples = _Samples(t, q, np.gradient(q, t, axis=0))
    reference = GeodesicReference(
        samples, None, time_scale=ref.time_scale, rest_to_rest=ref.rest_to_rest
    )
    return reference, plan


__all__ = [
    "COUPLING_TOLERANCE",
    "TrackedReference",
    "build_reference",
    "goals_reference",
    "planned_reference",
    "reference_coupling",
    "reference_coupling_residual",
    "reference_geodesic",
    "tracked_reference",
]
