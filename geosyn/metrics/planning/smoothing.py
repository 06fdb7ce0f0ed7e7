"""Shortening a sampled path in the planner's metric, without an NLP.

`metric_shortcut` replaces a random stretch of a piecewise-linear path (between two
random points on it, not only its vertices: "partial shortcuts") by the straight joint
segment between them when that segment is valid and shorter in the metric (midpoint rule
on `PIECES` pieces per segment). `even_in_metric` then adds points on its segments so
that consecutive samples are about equally far apart in the metric: the path itself is
unchanged, and its energy with equally spaced times is then close to its squared metric
length (what a constant-speed traversal of it costs), so that it compares fairly with a
collocation's energy. `metric_smooth` then moves its samples down the discrete energy's
gradient (preconditioned by the metric, a sample held where its move would make a segment
invalid): joint-space segments bent towards the metric's geodesics, still without an NLP.
"""

from __future__ import annotations

import math
import time

import numpy as np

from geosyn.metrics.base import Metric
from geosyn.metrics.planning.rrt import Validity

__all__ = ["PIECES", "even_in_metric", "metric_shortcut", "metric_smooth", "segment_lengths"]

PIECES = 4
"""Midpoint-rule pieces per segment of the metric length of a joint segment."""


def segment_lengths(metric: Metric, path: np.ndarray, pieces: int = PIECES) -> np.ndarray:
    """(T - 1,) metric length of each straight segment of ``path`` (T, n) [rad], by the
    midpoint rule on ``pieces`` pieces per segment."""
    path = np.asarray(path, dtype=float)
    out = np.zeros(max(len(path) - 1, 0))
    for i, (a, b) in enumerate(zip(path[:-1], path[1:], strict=True)):
        d = (b - a) / pieces
        mids = a + ((np.arange(pieces) + 0.5) / pieces)[:, None] * (b - a)
        out[i] = sum(math.sqrt(max(float(d @ metric.G(m) @ d), 0.0)) for m in mids)
    return out


def _point(path: np.ndarray, cum: np.ndarray, s: float) -> tuple[np.ndarray, int]:
    """The point of ``path`` at joint arclength ``s`` and the index of its segment."""
    i = int(np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(path) - 2))
    span = cum[i + 1] - cum[i]
    u = 0.0 if span <= 0.0 else (s - cum[i]) / span
    return path[i] + u * (path[i + 1] - path[i]), i


def metric_shortcut(
    valid: Validity,
    metric: Metric,
    path: np.ndarray,
    *,
    resolution: float = 0.02,
    tries: int = 200,
    budget: float = 0.1,
    seed: int = 0,
) -> np.ndarray:
    """A path no longer in ``metric`` than ``path`` (T, n) [rad], valid where it was.

    Args:
        valid: batched validity check (see `geosyn.metrics.planning.rrt.Validity`).
        metric: the planner's metric (its ``G(q)``).
        path: (T, n) a valid piecewise-linear path [rad], T >= 2.
        resolution: check step of a new segment (2-norm) [rad].
        tries: most shortcuts tried.
        budget: wall-time limit [s].
        seed: seed of the random points.

    Returns:
        (T', n) the shortened path, same ends.
    """
    rng = np.random.default_rng(seed)
    path = np.asarray(path, dtype=float)
    t_end = time.perf_counter() + budget
    for _ in range(tries):
        if len(path) <= 2 or time.perf_counter() > t_end:
            break
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
        u, v = np.sort(rng.uniform(0.0, cum[-1], size=2))
        a, i = _point(path, cum, float(u))
        b, j = _point(path, cum, float(v))
        if j == i:  # on one segment: already straight
            continue
        old = segment_lengths(metric, np.vstack([a, path[i + 1 : j + 1], b])).sum()
        new = segment_lengths(metric, np.array([a, b]))[0]
        if new >= old:
            continue
        k = max(1, int(math.ceil(float(np.linalg.norm(b - a)) / resolution)))
        if not np.all(valid(a + (np.arange(k + 1) / k)[:, None] * (b - a))):
            continue
        path = np.vstack([path[: i + 1], a, b, path[j + 1 :]])
        keep = np.concatenate([[True], np.linalg.norm(np.diff(path, axis=0), axis=1) > 1e-12])
        path = path[keep]  # a or b on a vertex
    return path


def even_in_metric(metric: Metric, path: np.ndarray, samples: int) -> np.ndarray:
    """``path`` (T, n) [rad] with points added on its segments, about ``samples`` - 1
    pieces of about equal metric length in all (each segment at least one); the same
    curve."""
    path = np.asarray(path, dtype=float)
    lengths = segment_lengths(metric, path)
    total = float(lengths.sum())
    if total <= 0.0:
        return path
    counts = np.maximum(1, np.rint(lengths / total * (samples - 1)).astype(int))
    out = [path[:1]]
    for a, b, k in zip(path[:-1], path[1:], counts, strict=True):
        out.append(a + (np.arange(1, k + 1) / k)[:, None] * (b - a))
    return np.vstack(out)


def _energy_gradient(metric: Metric, path: np.ndarray, h: float = 1e-6) -> tuple[float, np.ndarray]:
    """(discrete energy, (T, n) its gradient) of ``path`` (T, n) [rad]: ``E = (T - 1)
    sum_i d_i^T G(m_i) d_i`` (``d_i`` the segments, ``m_i`` their midpoints), the
    derivative of ``G`` by forward differences of step ``h`` [rad]."""
    N, n = len(path) - 1, path.shape[1]
    d, m = np.diff(path, axis=0), 0.5 * (path[1:] + path[:-1])
    Gd = np.empty_like(d)
    dq = np.empty_like(d)  # gradient of d^T G(q) d at m
    energy = 0.0
    eye = h * np.eye(n)
    for i in range(N):
        G = metric.G(m[i])
        Gd[i] = G @ d[i]
        base = float(d[i] @ Gd[i])
        energy += base
        dq[i] = [(float(d[i] @ metric.G(m[i] + e) @ d[i]) - base) / h for e in eye]
    grad = np.zeros_like(path)
    grad[1:] += N * (2.0 * Gd + 0.5 * dq)
    grad[:-1] += N * (-2.0 * Gd + 0.5 * dq)
    grad[[0, -1]] = 0.0  # the ends are fixed
    return N * energy, grad


def metric_smooth(
    valid: Validity,
    metric: Metric,
    path: np.ndarray,
    *,
    resolution: float = 0.02,
    budget: float = 0.05,
    step: float = 0.5,
) -> np.ndarray:
    """A path of lower discrete energy in ``metric`` than ``path`` (T, n) [rad] (same
    samples and ends), valid where checked: steps of the interior samples along the
    energy's gradient preconditioned by ``G^-1 / (4 (T - 1))`` (the energy's Hessian in
    one sample, its neighbours held), a sample whose move would make one of its segments
    invalid (checked every ``resolution`` [rad], 2-norm) held where it was, a step
    halved (from ``step``) when the energy does not fall; until ``budget`` [s] is spent.
    O(T n) metric evaluations per step.
    """
    path = np.asarray(path, dtype=float).copy()
    if len(path) <= 2:
        return path
    t_end = time.perf_counter() + budget
    N = len(path) - 1
    energy, grad = _energy_gradient(metric, path)
    while time.perf_counter() < t_end and step > 1e-3:
        move = np.array([np.linalg.solve(metric.G(q), g) for q, g in zip(path, grad, strict=True)])
        trial = path - step * move / (4.0 * N)
        for _ in range(4):  # hold the samples next to an invalid segment
            bad = _invalid_segments(valid, trial, resolution)
            if not bad.any():
                break
            held = np.zeros(len(path), dtype=bool)
            held[:-1] |= bad
            held[1:] |= bad
            trial[held] = path[held]
        else:
            step *= 0.5
            continue
        new_energy, new_grad = _energy_gradient(metric, trial)
        if new_energy >= energy:
            step *= 0.5
            continue
        path, energy, grad = trial, new_energy, new_grad
    return path


def _invalid_segments(valid: Validity, path: np.ndarray, resolution: float) -> np.ndarray:
    """(T - 1,) which segments of ``path`` (T, n) have an invalid configuration, checked
    every ``resolution`` [rad] (2-norm), ends included."""
    pts, owner = [], []
    for i, (a, b) in enumerate(zip(path[:-1], path[1:], strict=True)):
        k = max(1, int(math.ceil(float(np.linalg.norm(b - a)) / resolution)))
        pts.append(a + (np.arange(k + 1) / k)[:, None] * (b - a))
        owner.append(np.full(k + 1, i))
    ok = valid(np.vstack(pts))
    bad = np.zeros(len(path) - 1, dtype=bool)
    np.logical_or.at(bad, np.concatenate(owner), ~ok)
    return bad
