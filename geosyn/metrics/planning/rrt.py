"""RRT-Connect in joint space: a seeded, time-bounded global seed for collocation.

Kuffner & LaValle's RRT-Connect: two trees, from the start and from the goal, grown
towards uniform samples within the joint limits; each new node of one tree is connected
greedily to the other. The trees are balanced (the turn passes to the other tree unless
it has at least twice the nodes, so a tree stuck in a narrow place grows until it is
out), and the sampled tree's extension has a dynamic domain (Yershova, Jaillet, Simeon
& LaValle 2005, "Dynamic-domain RRTs", ICRA): a node whose extension failed only takes
samples within its radius, which shrinks at each further failure and grows at each
success; as in VAMP's RRT-Connect (Thomason et al. 2024). On the Panda's 13 benchmark
scenes (`benchmarks/planning_scenes.py`, 20 seeds each) the two with the narrowest
ways (shelf_compartments, window) took 70 / 47 ms in median and up to 342 / 467 ms
before, 8.5 / 1.9 ms and up to 20 / 6 ms with both and `RRT_STEP` 0.6 rad rather than
0.3 (measured, in C). Edges are checked at a fixed joint-space resolution with
a batched validity function. The found path is then shortened by random shortcuts. It
only needs to reach the goal around the obstacles: `Planner` hands it to collocation,
which makes it minimum-energy.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_vec3

__all__ = [
    "DYNAMIC_DOMAIN",
    "RRT_STEP",
    "Near",
    "SegmentValidity",
    "Validity",
    "check_near",
    "rrt_connect",
    "segment_points",
    "shortcut",
    "string_pull",
]

Validity = Callable[[np.ndarray], np.ndarray]
"""``valid(Q (K, n)) -> (K,) bool``: which configurations are collision-free."""

RRT_STEP = 0.6
"""Default largest extension of a tree per iteration (2-norm) [rad]."""

DYNAMIC_DOMAIN = (2.0, 0.6, 1e-4)
"""Default dynamic domain of the sampled tree's extension: (radius [rad] a node takes at
its first failed extension, smallest radius [rad], alpha: the radius shrinks by the
factor 1 - alpha at each further failure, grows by 1 + alpha at each success)."""

Near = tuple[np.ndarray, np.ndarray, float]
"""``(lo (n,), hi (n,), share)``: a box [rad] inside an RRT-Connect's sampling box and
the share of its samples drawn there (`rrt_connect`'s ``near``)."""

SegmentValidity = Callable[[np.ndarray, np.ndarray, float], bool]
"""``segment(a (n,), b (n,), resolution) -> bool``: whether the joint segment from ``a``
to ``b`` is collision-free every ``resolution`` [rad] (``a`` itself not checked), e.g.
`geosyn.metrics.planning.planner.Planner.segment_valid` (in C, stopping at the first
collision)."""


def segment_points(a: np.ndarray, b: np.ndarray, resolution: float,
                   first: bool = False) -> np.ndarray:  # fmt: skip
    """(k, n) the points ``a + (i / k) (b - a)``, i = 1 .. k (0 .. k with ``first``), of
    the joint segment ``a`` -> ``b`` (n,) [rad], ``k = max(1, ceil(|b - a| /
    resolution))`` (2-norm, ``resolution`` [rad]): what every segment check of the
    planner's sampling checks (in numpy; the C check the same)."""
    k = max(1, int(np.ceil(float(np.linalg.norm(b - a)) / resolution)))
    return a + (np.arange(0 if first else 1, k + 1) / k)[:, None] * (b - a)


def _edge_valid(valid: Validity, a: np.ndarray, b: np.ndarray, resolution: float,
                segment: SegmentValidity | None = None) -> bool:  # fmt: skip
    if segment is not None:
        return segment(a, b, resolution)
    return bool(np.all(valid(segment_points(a, b, resolution))))


class _Tree:
    def __init__(self, root: np.ndarray, capacity: int) -> None:
        self.q = np.empty((capacity, root.size))
        self.parent = np.full(capacity, -1, dtype=int)
        self.radius = np.full(capacity, np.inf)  # the dynamic domain's, per node
        self.q[0] = root
        self.size = 1

    def nearest(self, q: np.ndarray) -> int:
        return int(np.argmin(np.sum((self.q[: self.size] - q) ** 2, axis=1)))

    def add(self, q: np.ndarray, parent: int) -> int:
        self.q[self.size] = q
        self.parent[self.size] = parent
        self.size += 1
        return self.size - 1

    def branch(self, i: int) -> np.ndarray:
        out = []
        while i >= 0:
            out.append(self.q[i])
            i = int(self.parent[i])
        return np.array(out)  # node i back to the root


def check_near(near: Near | None, lo: np.ndarray, hi: np.ndarray) -> Near:
    """``near`` (`Near`) as float arrays and a float, or `InvalidArgument` naming what is
    allowed: its box within ``[lo, hi]`` (n,) [rad], lower <= upper, share in [0, 1].
    None: ``(lo, hi, 0.0)``, no share of the samples."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    if near is None:
        return lo, hi, 0.0
    try:
        n_lo, n_hi = (np.asarray(x, dtype=float).reshape(lo.shape) for x in near[:2])
        share = float(near[2])
    except (TypeError, ValueError, IndexError) as err:
        raise InvalidArgument(f"near: (lo (n,), hi (n,), share) with n = {lo.size}, got "
                              f"{near!r}") from err  # fmt: skip
    if not (np.all(lo <= n_lo) and np.all(n_lo <= n_hi) and np.all(n_hi <= hi)
            and 0.0 <= share <= 1.0):  # fmt: skip
        raise InvalidArgument("near: a box with lo <= near lo <= near hi <= hi [rad] and a "
                              f"share in [0, 1], got share {share!r}")  # fmt: skip
    return n_lo, n_hi, share


def check_domain(domain: tuple[float, float, float] | None) -> tuple[float, float, float] | None:
    """``domain`` (see `rrt_connect`) as floats, or `InvalidArgument` naming what is allowed."""
    if domain is None:
        return None
    radius, smallest, alpha = check_vec3(domain, "domain")  # finite reals, no booleans
    if not (0.0 < smallest <= radius and 0.0 <= alpha < 1.0):
        raise InvalidArgument(f"domain: 0 < smallest radius <= radius [rad] and "
                              f"0 <= alpha < 1, got {domain!r}")  # fmt: skip
    return radius, smallest, alpha


def rrt_connect(
    valid: Validity,
    q0: np.ndarray,
    q1: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    *,
    step: float = RRT_STEP,
    resolution: float = 0.05,
    budget: float = 2.0,
    seed: int = 0,
    max_nodes: int = 20000,
    domain: tuple[float, float, float] | None = DYNAMIC_DOMAIN,
    balance: bool = True,
    near: Near | None = None,
) -> tuple[np.ndarray | None, int]:
    """A collision-free piecewise-linear path from ``q0`` to ``q1``, or None.

    Args:
        valid: batched validity check (see `Validity`).
        q0: (n,) start [rad] (assumed valid).
        q1: (n,) goal [rad] (assumed valid).
        q_min: (n,) lower joint limits [rad] (the sampling box).
        q_max: (n,) upper joint limits [rad].
        step: largest extension of a tree per iteration (2-norm) [rad].
        resolution: edge checking step (2-norm) [rad].
        budget: wall-time limit [s].
        seed: seed of the sampler.
        max_nodes: largest number of nodes per tree.
        domain: the sampled tree's dynamic domain (`DYNAMIC_DOMAIN`: radius [rad],
            smallest radius [rad], alpha); None: none (plain RRT-Connect).
        balance: the turn passes to the other tree only when it has fewer than twice
            the nodes of the tree that grew; False: the trees take turns.
        near: (lo (n,), hi (n,), share): that share of the samples drawn from this box
            inside ``[q_min, q_max]`` (e.g. round the ends: shorter first paths), the
            rest from the whole box (a connection wherever the whole box has one); None:
            all from the whole box (and no draw for the choice).

    Returns:
        ``(path, nodes)``: (T, n) path from ``q0`` to ``q1`` (None if none was found within
        the budget) and the number of tree nodes grown.
    """
    domain = check_domain(domain)
    n_lo, n_hi, share = check_near(near, q_min, q_max)
    t_end = time.perf_counter() + budget
    rng = np.random.default_rng(seed)
    if _edge_valid(valid, q0, q1, resolution):
        return np.array([q0, q1]), 2
    trees = [_Tree(q0, max_nodes), _Tree(q1, max_nodes)]
    from_start = trees[0]  # ``trees`` swaps when the turn passes

    def extend(tree: _Tree, target: np.ndarray, sampled: bool) -> tuple[int, bool]:
        i = tree.nearest(target)
        d = target - tree.q[i]
        dist = float(np.linalg.norm(d))
        dd, r = (domain if sampled else None), tree.radius[i]  # the connection has none
        if dd is not None and dist > r:
            return -1, False  # outside the nearest node's domain: nothing checked
        reached = dist <= step
        new = target if reached else tree.q[i] + d * (step / dist)
        if not _edge_valid(valid, tree.q[i], new, resolution):
            if dd is not None:
                tree.radius[i] = dd[0] if math.isinf(r) else max(r * (1 - dd[2]), dd[1])
            return -1, False
        if dd is not None and not math.isinf(r):
            tree.radius[i] = r * (1 + dd[2])
        return tree.add(new, i), reached

    while time.perf_counter() < t_end and max(t.size for t in trees) < max_nodes - 1:
        a, b = trees
        box = (n_lo, n_hi) if share > 0.0 and rng.uniform() < share else (q_min, q_max)
        j, _ = extend(a, rng.uniform(*box), True)
        if j >= 0:
            target = a.q[j]
            while time.perf_counter() < t_end and b.size < max_nodes - 1:
                k, reached = extend(b, target, False)
                if k < 0:
                    break
                if reached:
                    path = np.vstack([a.branch(j)[::-1], b.branch(k)[1:]])
                    if a is not from_start:  # tree a grew from the goal
                        path = path[::-1]
                    return path, trees[0].size + trees[1].size
        if not balance or b.size < 2 * a.size:
            trees.reverse()
    return None, trees[0].size + trees[1].size


def shortcut(
    valid: Validity,
    path: np.ndarray,
    *,
    resolution: float = 0.05,
    tries: int = 100,
    budget: float = 0.2,
    seed: int = 0,
    segment: SegmentValidity | None = None,
) -> np.ndarray:
    """Shorten a valid path (T, n) by random shortcuts between its vertices (seeded;
    ``segment``: checks a shortcut instead of ``valid``)."""
    rng = np.random.default_rng(seed)
    path = np.asarray(path, dtype=float)
    t_end = time.perf_counter() + budget
    for _ in range(tries):
        if len(path) <= 2 or time.perf_counter() > t_end:
            break
        i, j = sorted(rng.choice(len(path), size=2, replace=False))
        if j - i < 2:
            continue
        if _edge_valid(valid, path[i], path[j], resolution, segment):
            path = np.vstack([path[: i + 1], path[j:]])
    return path


def string_pull(
    segment: SegmentValidity,
    path: np.ndarray,
    *,
    resolution: float = 0.05,
    deadline: float = math.inf,
) -> np.ndarray:
    """``path`` (T, n) [rad] with its vertices skipped greedily: from each kept vertex,
    the straight segment to the farthest later vertex that ``segment`` accepts (the next
    vertex's is valid already). Deterministic; O(T^2) segment checks at most, in
    practice about T; the same ends, never longer in joint space. Once
    ``time.perf_counter()`` passes ``deadline`` [s], the vertices left are kept as they
    are."""
    path = np.asarray(path, dtype=float)
    kept, i = [path[0]], 0
    while i < len(path) - 1:
        j = len(path) - 1
        while j > i + 1:
            if time.perf_counter() > deadline:  # the vertices left as they are
                return np.array(kept + list(path[i + 1 :]))
            if segment(path[i], path[j], resolution):
                break
            j -= 1
        kept.append(path[j])
        i = j
    return np.array(kept)
