"""Shortening a sampled path in the planner's metric, without an NLP.

`metric_shortcut` replaces a random stretch of a piecewise-linear path (between two
random points on it, not only its vertices: "partial shortcuts") by the straight joint
segment between them when that segment is valid and shorter in the metric (midpoint rule
on `PIECES` pieces per segment). `even_in_metric` then adds points on its segments so
that consecutive samples are about equally far apart in the metric: the path itself is
unchanged, and its energy with equally spaced times is then close to its squared metric
length (what a constant-speed traversal of it costs), so that it compares fairly with a
collocation's energy. `geosyn.metrics.planning.relax.metric_relax` then bends the
samples towards the metric's minimum-energy path, still without an NLP.
"""

from __future__ import annotations

import time

import numpy as np

from geosyn.metrics.base import Metric
from geosyn.metrics.planning.rrt import SegmentValidity, Validity, segment_points

__all__ = [
    "PIECES",
    "densify",
    "even_in_metric",
    "metric_length",
    "metric_shortcut",
    "pair_lengths",
    "segment_lengths",
]

PIECES = 4
"""Midpoint-rule pieces per segment of the metric length of a joint segment."""


def densify(path: np.ndarray, factor: int) -> np.ndarray:
    """(factor (T - 1) + 1, n): ``path`` (T, n) with ``factor - 1`` linear points per segment."""
    path = np.asarray(path, dtype=float)
    s = np.arange(factor)[:, None, None] / factor
    inner = path[:-1][None] + s * np.diff(path, axis=0)[None]
    return np.vstack([inner.transpose(1, 0, 2).reshape(-1, path.shape[1]), path[-1:]])


def metric_length(metric: Metric, path: np.ndarray) -> float:
    """Metric length of the piecewise-linear ``path`` (T, n) [rad]: the sum over segments
    of ``sqrt(dq^T G(q_mid) dq)`` (midpoint rule, one piece per segment)."""
    return float(segment_lengths(metric, path, pieces=1).sum())


def segment_lengths(metric: Metric, path: np.ndarray, pieces: int = PIECES) -> np.ndarray:
    """(T - 1,) metric length of each straight segment of ``path`` (T, n) [rad], by the
    midpoint rule on ``pieces`` pieces per segment."""
    path = np.asarray(path, dtype=float)
    if len(path) < 2:
        return np.zeros(0)
    return pair_lengths(metric, path[:-1], path[1:], pieces)


def pair_lengths(metric: Metric, X: np.ndarray, Y: np.ndarray, pieces: int = PIECES) -> np.ndarray:
    """(K,) metric length of each straight segment ``X[k]`` -> ``Y[k]`` ((K, n) [rad]
    each), by the midpoint rule on ``pieces`` pieces per segment (one batched
    ``G_many``)."""
    step = Y - X  # (K, n)
    s = (np.arange(pieces) + 0.5) / pieces
    mids = X[:, None] + s[None, :, None] * step[:, None]  # (K, pieces, n)
    d = np.repeat(step / pieces, pieces, axis=0)  # each piece's step, (K pieces, n)
    G = metric.G_many(mids.reshape(-1, X.shape[1]))
    sq = np.einsum("ka,kab,kb->k", d, G, d)
    return np.sqrt(np.maximum(sq, 0.0)).reshape(-1, pieces).sum(axis=1)


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
    segment: SegmentValidity | None = None,
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
        segment: checks a new segment instead of ``valid`` (e.g. in C, stopping at the
            first collision).

    Returns:
        (T', n) the shortened path, same ends.
    """
    rng = np.random.default_rng(seed)
    path = np.asarray(path, dtype=float)
    t_end = time.perf_counter() + budget
    lengths = segment_lengths(metric, path)  # of each segment, kept up to date
    for _ in range(tries):
        if len(path) <= 2 or time.perf_counter() > t_end:
            break
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
        u, v = np.sort(rng.uniform(0.0, cum[-1], size=2))
        a, i = _point(path, cum, float(u))
        b, j = _point(path, cum, float(v))
        if j == i:  # on one segment: already straight
            continue
        ends = pair_lengths(metric, np.array([a, path[j], a]), np.array([path[i + 1], b, b]))
        old = float(ends[0]) + float(lengths[i + 1 : j].sum()) + float(ends[1])
        new = float(ends[2])
        if new >= old:
            continue
        if not _segment_ok(valid, segment, a, b, resolution):
            continue
        first, last = pair_lengths(metric, np.array([path[i], b]), np.array([a, path[j + 1]]))
        pieces = [float(first), new, float(last)]
        path = np.vstack([path[: i + 1], a, b, path[j + 1 :]])
        lengths = np.concatenate([lengths[:i], pieces, lengths[j + 1 :]])
        keep = np.concatenate([[True], np.linalg.norm(np.diff(path, axis=0), axis=1) > 1e-12])
        path, lengths = path[keep], lengths[keep[1:]]  # a or b on a vertex
    return path


def _segment_ok(valid: Validity, segment: SegmentValidity | None, a: np.ndarray,
                b: np.ndarray, resolution: float) -> bool:  # fmt: skip
    """Whether the joint segment ``a`` -> ``b`` is valid every ``resolution`` [rad],
    ``a`` included (by ``segment`` when given)."""
    if segment is not None:
        return bool(valid(a[None])[0]) and segment(a, b, resolution)
    return bool(np.all(valid(segment_points(a, b, resolution, first=True))))


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
