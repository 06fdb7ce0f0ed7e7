"""Sequences of geodesic synergies: a task given as goals becomes geodesics joined in time.

A task ``q_0 -> q_1 -> ... -> q_K`` (joint goals, or Cartesian goals reached by synergy
weights, `reach_sequence`) becomes K segments; segment i is the geodesic of its metric
``G_i`` from ``q_i`` to ``q_{i+1}`` (the metric may change between segments, e.g. when a
load is grasped). Segment i is the path :math:`\\gamma_i(s)`, :math:`s \\in [0, 1]`, in its
affine (geodesic) parameter, traversed in ``T_i`` seconds with the quintic time law

.. math::
    q(t) = \\gamma_i(\\sigma(u)), \\quad u = (t - t_i) / T_i, \\quad
    \\sigma(u) = 10 u^3 - 15 u^4 + 6 u^5 .

Why the segments meet at rest: two geodesics of one metric that meet with the same
velocity are the same geodesic (uniqueness of the geodesic ODE), so a sequence through
genuinely distinct goals cannot be C1 with every segment at constant geodesic speed.
The time law keeps each segment's *path* a geodesic (``gamma_i'' + Gamma(gamma_i',
gamma_i') = 0`` in ``s``) and makes position, velocity and acceleration continuous at every
junction (velocity and acceleration are zero there). Where a segment's synergies are based
elsewhere, their velocities are parallel-transported to the segment's start
(`reach_sequence`, through `geosyn.synergies.reach`).

`straight_sequence` is the baseline through the same goals: straight joint-space lines
with the same time law, i.e. the joint-space minimum-jerk motion from rest to rest.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from geosyn.core.interpolation import hermite_quintic_coefficients
from geosyn.core.types import Matrix, Vector
from geosyn.core.validation import check_int, check_positive
from geosyn.metrics.base import Metric
from geosyn.metrics.geodesic import exp
from geosyn.robots.robot import Robot
from geosyn.synergies.errors import InvalidSynergyInput, synergy_input
from geosyn.synergies.reach import ReachOutsideLimits, reach
from geosyn.synergies.synergy import (
    GeodesicSynergy,
    as_vector,
    check_metric,
    checked_log,
)


def time_law(u: float) -> tuple[float, float, float]:
    """Quintic rest-to-rest time law and its first two derivatives in ``u`` in [0, 1]."""
    u2 = u * u
    return (
        u2 * u * (10.0 - 15.0 * u + 6.0 * u2),
        30.0 * u2 * (1.0 - u) ** 2,
        60.0 * u * (1.0 - u) * (1.0 - 2.0 * u),
    )


@dataclass(frozen=True, eq=False)
class SequenceSegment:
    """One segment: a path in its own parameter ``s`` in [0, 1], timed by the time law.

    Attributes:
        metric: the metric whose geodesic the path is (None for a path that is not a
            geodesic: a straight line, a planner's constrained path).
        s: (S,) path parameter samples, uniform in [0, 1].
        q: (S, n) path positions [rad].
        dq: (S, n) path derivative dq/ds [rad].
        ddq: (S, n) second derivative d^2q/ds^2 [rad] (the metric's geodesic acceleration
            along a geodesic, 0 along a straight line).
        t0: start time in the sequence [s].
        duration: traversal time T [s].
        weights: (m,) synergy weights of the segment, or None.
        reach_error: distance of the frame from its Cartesian goal [m] (NaN for joint goals).
    """

    metric: Metric | None
    s: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    t0: float
    duration: float
    weights: np.ndarray | None = None
    reach_error: float = float("nan")
    _coef: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        coef = hermite_quintic_coefficients(self.s, self.q, self.dq, self.ddq)
        object.__setattr__(self, "_coef", coef)

    @property
    def start(self) -> Vector:
        """(n,) start configuration [rad]."""
        return self.q[0].copy()

    @property
    def goal(self) -> Vector:
        """(n,) end configuration [rad]."""
        return self.q[-1].copy()

    def path_point(self, s: float) -> tuple[Vector, Vector, Vector]:
        """Path position, first and second derivative in ``s`` (quintic Hermite, C2)."""
        s = min(max(float(s), 0.0), 1.0)
        h = float(self.s[1] - self.s[0])
        k = min(int(s / h), len(self.s) - 2)
        x = s - float(self.s[k])
        c = self._coef[k]
        p = np.arange(6, dtype=np.float64)
        pos = (x**p) @ c
        der = (p[1:] * x ** (p[1:] - 1)) @ c[1:]
        acc = (p[2:] * (p[2:] - 1) * x ** (p[2:] - 2)) @ c[2:]
        return pos, der, acc

    def sample(self, t: float) -> tuple[Vector, Vector, Vector]:
        """``(q, v, a)`` at sequence time ``t`` [s], clamped to the segment's interval.

        Returns:
            (n,) [rad], (n,) [rad/s], (n,) [rad/s^2].
        """
        u = min(max((float(t) - self.t0) / self.duration, 0.0), 1.0)
        sig, dsig, ddsig = time_law(u)
        T = self.duration
        g, dg, ddg = self.path_point(sig)
        sd, sdd = dsig / T, ddsig / (T * T)
        return g, dg * sd, ddg * sd * sd + dg * sdd

    def geodesic_residual(self) -> float:
        """Largest ``|d2q/ds2 + Gamma(q, dq/ds)|`` along the path [rad], derivatives by
        4th-order central finite differences of the positions only (0 is exact)."""
        if self.metric is None:
            raise InvalidSynergyInput("a straight segment has no metric", "metric")
        h = float(self.s[1] - self.s[0])
        q = self.q
        qd = (-q[4:] + 8.0 * q[3:-1] - 8.0 * q[1:-3] + q[:-4]) / (12.0 * h)
        qdd = (-q[4:] + 16.0 * q[3:-1] - 30.0 * q[2:-2] + 16.0 * q[1:-3] - q[:-4]) / (12.0 * h * h)
        r = 0.0
        for k in range(len(qd)):
            gamma = self.metric.geodesic_acceleration(q[k + 2], qd[k])
            r = max(r, float(np.max(np.abs(qdd[k] - gamma))))
        return r


class SynergySequence:
    """Segments joined in time (see the module doc); a reference ``sample(t)``.

    Args:
        segments: the segments, each starting where the previous one ends.

    Raises:
        InvalidSynergyInput: no segments, or a segment not starting at the previous goal
            (1e-9 rad) or at the previous end time.
    """

    def __init__(self, segments: Sequence[SequenceSegment]) -> None:
        segs = tuple(segments)
        if not segs:
            raise InvalidSynergyInput("a sequence needs at least one segment", "segments")
        for i in range(1, len(segs)):
            gap = float(np.max(np.abs(segs[i].q[0] - segs[i - 1].q[-1])))
            if gap > 1e-9 or abs(segs[i].t0 - segs[i - 1].t0 - segs[i - 1].duration) > 1e-12:
                raise InvalidSynergyInput(
                    f"segments[{i}] must start where and when segments[{i - 1}] ends "
                    f"(position gap {gap:.3g} rad)",
                    "segments",
                )
        self.segments = segs
        self.n = int(segs[0].q.shape[1])
        self.t0 = segs[0].t0
        self.duration = float(sum(s.duration for s in segs))

    @property
    def junction_times(self) -> Vector:
        """(K-1,) times where one segment ends and the next starts [s]."""
        return np.array([s.t0 for s in self.segments[1:]])

    @property
    def waypoints(self) -> Matrix:
        """(K+1, n) start, junction and goal configurations [rad]."""
        return np.array([self.segments[0].start] + [s.goal for s in self.segments])

    def segment_index(self, t: float) -> int:
        """Index of the segment active at time ``t`` (clamped to the first/last)."""
        for i, seg in enumerate(self.segments):
            if t < seg.t0 + seg.duration:
                return i
        return len(self.segments) - 1

    def sample(self, t: float) -> tuple[Vector, Vector, Vector]:
        """``(q, v, a)`` at time ``t`` [s]; the goal at rest after the end."""
        return self.segments[self.segment_index(float(t))].sample(t)

    def junction_jumps(self) -> Matrix:
        """(K-1, 3) max-norm jumps of position [rad], velocity [rad/s] and acceleration
        [rad/s^2] at each junction (left limit of segment i vs right limit of segment i+1)."""
        out = []
        for a, b in zip(self.segments[:-1], self.segments[1:], strict=True):
            left, right = a.sample(a.t0 + a.duration), b.sample(b.t0)
            out.append([float(np.max(np.abs(x - y))) for x, y in zip(left, right, strict=True)])
        return np.array(out).reshape(-1, 3)

    def trajectory(self, dt: float) -> tuple[Vector, Matrix, Matrix, Matrix]:
        """Samples every ``dt`` [s] from ``t0`` to the end: t (T,), q, v, a (T, n)."""
        dt = check_positive(dt, "dt", "s")
        t = self.t0 + np.linspace(0.0, self.duration, int(round(self.duration / dt)) + 1)
        rows = [self.sample(ti) for ti in t]
        return t, *(np.array([r[j] for r in rows]) for j in range(3))  # type: ignore[return-value]

    def energy(self, metric: Metric | Sequence[Metric], dt: float = 2e-3) -> float:
        """``1/2 integral qdot^T G(q) qdot dt`` of the timed motion [J s].

        Args:
            metric: the metric, or one per segment (e.g. the loaded metric while a load
                is carried).
            dt: sample period of Simpson's rule on each segment [s].
        """
        from scipy.integrate import simpson  # heavy (with scipy.optimize): imported where used

        dt = check_positive(dt, "dt", "s")
        ms = _metrics(metric, len(self.segments))
        total = 0.0
        for seg, m in zip(self.segments, ms, strict=True):
            t = seg.t0 + np.linspace(0.0, seg.duration, max(int(round(seg.duration / dt)), 2) + 1)
            e = []
            for ti in t:
                q, v, _ = seg.sample(ti)
                e.append(v @ m.G(q) @ v)
            total += float(0.5 * simpson(np.array(e), x=t))
        return total

    def path_energy(self, metric: Metric | Sequence[Metric]) -> float:
        """Energy of the paths at constant speed in their own parameter [J s]:
        ``sum_i 1/(2 T_i) integral_0^1 gamma_i'^T G gamma_i' ds`` (Simpson on the path
        samples). A geodesic of ``G`` minimises it among paths with the same end points;
        the time law multiplies a geodesic's value by 10/7.

        Args:
            metric: the metric, or one per segment.
        """
        from scipy.integrate import simpson  # heavy (with scipy.optimize): imported where used

        ms = _metrics(metric, len(self.segments))
        total = 0.0
        for seg, m in zip(self.segments, ms, strict=True):
            e = np.array([d @ m.G(q) @ d for q, d in zip(seg.q, seg.dq, strict=True)])
            total += float(0.5 * simpson(e, x=seg.s)) / seg.duration
        return total


def _check_goals(waypoints: object, durations: object, n: int) -> tuple[Matrix, Vector]:
    with synergy_input("waypoints"):
        W = np.asarray(waypoints, dtype=np.float64)
        if W.ndim != 2 or W.shape[0] < 2 or W.shape[1] != n or not np.all(np.isfinite(W)):
            raise InvalidSynergyInput(
                f"waypoints must be a finite (K+1, {n}) array with K >= 1, got shape {W.shape}",
                "waypoints",
            )
    with synergy_input("durations"):
        T = np.atleast_1d(np.asarray(durations, dtype=np.float64))
        if T.shape != (W.shape[0] - 1,) or not np.all(np.isfinite(T)) or np.any(T <= 0.0):
            raise InvalidSynergyInput(
                f"durations must hold {W.shape[0] - 1} times > 0 [s], got {T}", "durations"
            )
    return W, T


def _metrics(metrics: Metric | Sequence[Metric], k: int) -> list[Metric]:
    if isinstance(metrics, Metric):
        return [metrics] * k
    ms = [check_metric(m) for m in metrics]
    if len(ms) != k:
        raise InvalidSynergyInput(f"metrics must hold one metric per segment ({k})", "metrics")
    return ms


def geodesic_segment(
    metric: Metric,
    q0: Vector,
    v0: Vector,
    t0: float,
    duration: float,
    steps: int,
    weights: Vector | None = None,
    reach_error: float = float("nan"),
) -> SequenceSegment:
    """The segment traversing ``exp_q0(s v0)``, s in [0, 1], in ``duration`` [s] from ``t0``."""
    g = exp(metric, q0, v0, duration=1.0, steps=steps)
    a = np.array([metric.geodesic_acceleration(q, v) for q, v in zip(g.q, g.v, strict=True)])
    return SequenceSegment(metric, g.t, g.q, g.v, a, t0, duration, weights, reach_error)


def geodesic_sequence(
    metrics: Metric | Sequence[Metric],
    waypoints: Matrix,
    durations: Sequence[float] | Vector,
    *,
    t0: float = 0.0,
    steps: int = 200,
) -> SynergySequence:
    """Geodesics of ``metrics[i]`` from ``waypoints[i]`` to ``waypoints[i+1]`` (log map).

    Args:
        metrics: one metric, or one per segment (K).
        waypoints: (K+1, n) start, via and goal configurations [rad].
        durations: (K,) traversal times [s].
        t0: start time [s].
        steps: RK4 steps of each geodesic (and path samples - 1).

    Raises:
        InvalidSynergyInput: bad shapes or durations.
        SynergyNotConverged: a log map did not converge (names the configurations).
    """
    with synergy_input("steps"):
        steps = check_int(steps, "steps", low=4)
    n = (metrics if isinstance(metrics, Metric) else check_metric(list(metrics)[0])).n
    W, T = _check_goals(waypoints, durations, n)
    ms = _metrics(metrics, W.shape[0] - 1)
    segs, t = [], float(t0)
    q = W[0]
    for i, metric in enumerate(ms):
        v0 = checked_log(metric, q, W[i + 1], steps=steps)
        seg = geodesic_segment(metric, q, v0, t, float(T[i]), steps)
        segs.append(seg)
        q, t = seg.q[-1], t + float(T[i])
    return SynergySequence(segs)


def straight_sequence(
    waypoints: Matrix, durations: Sequence[float] | Vector, *, t0: float = 0.0, steps: int = 200
) -> SynergySequence:
    """The baseline: straight joint-space lines through ``waypoints``, same time law.

    Args:
        waypoints: (K+1, n) configurations [rad].
        durations: (K,) traversal times [s].
        t0: start time [s].
        steps: path samples - 1 per segment.
    """
    with synergy_input("steps"):
        steps = check_int(steps, "steps", low=4)
    W, T = _check_goals(waypoints, durations, int(np.shape(waypoints)[-1]))
    s = np.linspace(0.0, 1.0, steps + 1)
    segs, t = [], float(t0)
    for i in range(len(T)):
        d = W[i + 1] - W[i]
        q = W[i] + s[:, None] * d
        dq = np.repeat(d[None, :], steps + 1, axis=0)
        segs.append(SequenceSegment(None, s, q, dq, np.zeros_like(q), t, float(T[i])))
        t += float(T[i])
    return SynergySequence(segs)


def reach_sequence(
    synergies: Sequence[GeodesicSynergy],
    targets: Matrix,
    frame: str,
    robot: Robot,
    durations: Sequence[float] | Vector,
    q_start: Vector | None = None,
    *,
    t0: float = 0.0,
    steps: int = 200,
    tol: float = 1e-4,
) -> SynergySequence:
    """Cartesian goals reached one after the other by synergy combinations.

    Segment i starts at the previous segment's end ``q_i``; the synergies' initial
    velocities are transported to ``q_i`` (`transported_velocities`, skipped when a
    synergy is based there) and `reach` finds the weights ``w_i`` whose combined geodesic
    brings ``frame`` to ``targets[i]``. The segment's path is that geodesic.

    Args:
        synergies: m synergies sharing one metric.
        targets: (K, 3) Cartesian goals in the world frame [m].
        frame: the frame brought to the goals.
        robot: the robot.
        durations: (K,) traversal times [s].
        q_start: (n,) start [rad]; the first synergy's base by default.
        t0: start time [s].
        steps: RK4 steps of each geodesic.
        tol: reach tolerance [m]; a segment missing its goal keeps its ``reach_error``.

    Raises:
        InvalidSynergyInput: bad input.
        ReachOutsideLimits: no motion inside the joint limits reaches a goal (its
            ``segment`` and message name the segment, its start and its target).
        SynergyNotConverged: a synergy base could not be joined to a segment start.
    """
    syns = list(synergies)
    metric = syns[0].metric if syns else None
    if metric is None:
        raise InvalidSynergyInput("synergies must hold at least one synergy", "synergies")
    with synergy_input("targets"):
        P = np.asarray(targets, dtype=np.float64)
        if P.ndim != 2 or P.shape[1] != 3 or P.shape[0] < 1 or not np.all(np.isfinite(P)):
            raise InvalidSynergyInput(
                f"targets must be a finite (K, 3) array [m], got shape {P.shape}", "targets"
            )
    T = np.atleast_1d(np.asarray(durations, dtype=np.float64))
    if T.shape != (P.shape[0],) or np.any(~(T > 0.0)):
        raise InvalidSynergyInput(f"durations must hold {P.shape[0]} times > 0 [s]", "durations")
    q = syns[0].q0.copy() if q_start is None else as_vector(q_start, metric.n, "q_start")
    segs, t = [], float(t0)
    for i, p in enumerate(P):
        try:
            res = reach(syns, p, frame, robot, q_start=q, steps=steps, tol=tol)
        except ReachOutsideLimits as err:
            raise ReachOutsideLimits(
                f"segment {i} (from q={np.round(q, 4).tolist()} to target"
                f" {np.round(p, 4).tolist()}): {err}",
                err.joint,
                err.value,
                err.limit,
                err.t,
                segment=i,
                q_start=q,
            ) from err
        v0 = res.trajectory.v[0]
        seg = geodesic_segment(metric, q, v0, t, float(T[i]), steps, res.weights, res.error)
        segs.append(seg)
        q, t = seg.q[-1], t + float(T[i])
    return SynergySequence(segs)


__all__ = [
    "SequenceSegment",
    "SynergySequence",
    "geodesic_segment",
    "geodesic_sequence",
    "reach_sequence",
    "straight_sequence",
    "time_law",
]
