"""The NLP of `geosyn.metrics.geodesic.collocation.Collocation`: its per-node functions
(compiled or not) and their assembly into IPOPT's objective, constraints and
hand-made derivatives over the nodes.

Building the per-node functions' expression graphs (forward kinematics, every sphere's
distance to every obstacle slot, their structured derivatives) takes ~10 s for a Panda
with ~45 spheres; reading them back takes < 1 s. For a `KineticEnergyMetric` they are
therefore kept, serialized by CasADi, under ``$GEOSYN_CACHE_DIR/nlp`` (else
``~/.cache/geosyn/nlp``), keyed by a hash of the robot model, the spheres, the obstacle
capacity and distance, the settings, CasADi's version and the source of every module that
builds them, and shared in a process by every collocation of the same key
(`clear_node_function_cache` empties both).
"""

from __future__ import annotations

import hashlib
import json
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import casadi as ca

from geosyn.core.cache_folder import default_cache_dir, fill_once, store_json
from geosyn.core.codegen import compile_library
from geosyn.metrics.base import Metric
from geosyn.metrics.geodesic.collocation_clearance import clearance_jacobian
from geosyn.metrics.geodesic.collocation_parts import node_functions

if TYPE_CHECKING:
    from geosyn.metrics.shaping.obstacle import ObstacleTerm

__all__ = [
    "CollocationNLP",
    "assemble_nlp",
    "clear_node_function_cache",
    "node_function_key",
    "per_node_functions",
]

_SOURCES = (
    "metrics/geodesic/collocation_parts.py",
    "metrics/geodesic/collocation_clearance.py",
    "metrics/geodesic/collocation_nlp.py",
    "metrics/kinetic.py",
    "metrics/base.py",
    "metrics/shaping/obstacle.py",
    "world/distance.py",
    "world/smooth.py",
    "world/shapes.py",
)
_MEMORY: dict[str, tuple[ca.Function, ...]] = {}


def _cache_dir() -> Path:
    return default_cache_dir().parent / "nlp"


def clear_node_function_cache() -> int:
    """Forget the per-node functions kept in this process and on disk (and lock files a
    killed build left); returns the number of files removed."""
    _MEMORY.clear()
    removed = 0
    if _cache_dir().is_dir():
        for f in [*_cache_dir().glob("nodefuns_*.json"), *_cache_dir().glob("nodefuns_*.lock")]:
            f.unlink(missing_ok=True)
            removed += 1
    return removed


def node_function_key(
    metric: Metric, clearance: ObstacleTerm | None, constraint_hessian: bool, softmin: float | None
) -> str | None:
    """The cache key of the per-node functions (hex), or None where the metric is not a
    plain `KineticEnergyMetric` (its graph is then not determined by the robot model)."""
    from geosyn.metrics.kinetic import KineticEnergyMetric

    if type(metric) is not KineticEnergyMetric:
        return None
    root = Path(__file__).resolve().parents[2]
    h = hashlib.sha256()
    h.update(metric.robot.model.saveToString().encode())
    for rel in (
        *_SOURCES,
        *sorted(str(p.relative_to(root)) for p in (root / "robots" / "symbolic").glob("*.py")),
    ):
        h.update((root / rel).read_bytes())
    if clearance is not None:
        h.update(json.dumps([clearance.capacity, clearance.distance,
                             [(s.joint, list(s.center), s.radius) for s in clearance.spheres]]).encode())  # fmt: skip
    h.update(f"{constraint_hessian}|{softmin!r}|{ca.CasadiMeta.version()}".encode())
    return h.hexdigest()[:32]


def _node_functions_cached(
    metric: Metric, clearance: ObstacleTerm | None, constraint_hessian: bool, softmin: float | None
) -> tuple[ca.Function, ...]:
    """`node_functions` plus the structured clearance Jacobian (last), from memory, the
    disk cache, or built (then stored)."""
    key = node_function_key(metric, clearance, constraint_hessian, softmin)
    if key is None:
        return _build_node_functions(metric, clearance, constraint_hessian, softmin)
    if key in _MEMORY:
        return _MEMORY[key]
    path = _cache_dir() / f"nodefuns_{key}.json"
    funcs = _read_node_functions(path)
    if funcs is None:  # one process builds them at a time; the others then read its file

        def make() -> tuple[ca.Function, ...]:
            built = _build_node_functions(metric, clearance, constraint_hessian, softmin)
            _write_node_functions(path, built)
            return built

        funcs = fill_once(
            path.with_suffix(".lock"), lambda: _read_node_functions(path, warn=False), make
        )
    _MEMORY[key] = funcs
    return funcs


def _build_node_functions(
    metric: Metric, clearance: ObstacleTerm | None, constraint_hessian: bool, softmin: float | None
) -> tuple[ca.Function, ...]:
    """`node_functions`, and the clearances' structured Jacobian last (with ``softmin``)."""
    funcs = node_functions(metric, clearance, constraint_hessian, softmin)
    if clearance is not None and softmin is not None:
        funcs = (*funcs, clearance_jacobian(clearance, softmin))
    return funcs


def _read_node_functions(path: Path, warn: bool = True) -> tuple[ca.Function, ...] | None:
    """The functions cached at ``path``, or None (missing, or damaged: built again, and
    warned if ``warn``)."""
    if not path.is_file():
        return None
    try:
        return tuple(ca.Function.deserialize(x) for x in json.loads(path.read_text()))
    except (OSError, ValueError, RuntimeError) as err:
        if warn:
            warnings.warn(f"node-function cache: {path.name} is damaged ({err!r}); "
                          "building it again", RuntimeWarning, 4)  # fmt: skip
        return None


def _write_node_functions(path: Path, funcs: tuple[ca.Function, ...]) -> None:
    """Store ``funcs`` at ``path`` atomically (an unwritable cache is warned, not fatal)."""
    store_json(path, [fn.serialize() for fn in funcs], "the node-function cache", 4)


def per_node_functions(
    metric: Metric,
    clearance: ObstacleTerm | None,
    constraint_hessian: bool,
    softmin: float | None,
    compile_mode: str,
) -> tuple[ca.Function, ...]:
    """The per-node functions (`node_functions`), compiled as ``compile_mode`` says
    (`geosyn.metrics.geodesic.collocation.COMPILE`), with the clearances' Jacobian by its
    structure where that applies: ``(segment energy, its derivatives, clearances, their
    Jacobian[, their multiplier-weighted Hessian])``."""
    cached = _node_functions_cached(metric, clearance, constraint_hessian, softmin)
    structured = clearance is not None and softmin is not None
    funcs = cached[:-1] if structured else cached
    if compile_mode != "none":
        # jac_<f> in the same library: first derivatives of f and g for CasADi's own
        # Lagrangian gradient (the hand-made derivatives of `assemble_nlp` serve IPOPT).
        jacs = [funcs[0].jacobian(), funcs[2].jacobian()]
        lib = compile_library("geosyn_collocation", [*funcs[:4], *jacs],
                              load=[f.name() for f in funcs[:4]])  # fmt: skip
        compiled = [lib[f.name()] for f in funcs[:4]]
        if compile_mode == "all" and len(funcs) > 4:
            # its own library: the first-order one above stays cached without it
            name = funcs[4].name()
            compiled.append(compile_library("geosyn_collocation_hessian", [funcs[4]])[name])
        funcs = tuple(compiled) + funcs[len(compiled) :]
    if clearance is not None and softmin is not None and compile_mode != "first-order":
        # the clearances' Jacobian by its structure (half the graph of the automatic
        # one, which "first-order" keeps from the library above), in a library of its own
        jac = cached[-1]
        if compile_mode == "all":
            jac = compile_library("geosyn_collocation_jacobian", [jac])[jac.name()]
        funcs = (*funcs[:3], jac, *funcs[4:])
    return funcs


class CollocationNLP(NamedTuple):
    """The assembled NLP: decision ``x`` ((N-1) n,), parameters ``p``
    (``q0, q1, metric parameters, obstacle parameters``), objective ``f``, constraints
    ``g``, and the hand-assembled derivatives IPOPT gets (``jac_g`` None without
    constraints)."""

    x: ca.MX
    p: ca.MX
    f: ca.MX
    g: ca.MX
    grad_f: ca.Function
    jac_g: ca.Function | None
    hess_l: ca.Function


def assemble_nlp(
    funcs: tuple[ca.Function, ...],
    n: int,
    N: int,
    npm: int,
    npc: int,
    m: int,
    subdivisions: int,
    constraint_hessian: bool,
) -> CollocationNLP:
    """The collocation NLP of ``N`` segments from the per-node functions
    (`per_node_functions`): energy by the midpoint rule, ``m`` clearance rows at each
    interior node and at ``subdivisions`` points inside each segment, a block-tridiagonal
    Lagrangian Hessian and a block-sparse constraint Jacobian (MX graph; allocates)."""
    seg, seg_d, clr, clr_j = funcs[:4]
    x = ca.MX.sym("x", n * (N - 1))
    p = ca.MX.sym("p", 2 * n + npm + npc)
    X = ca.reshape(x, n, N - 1)
    q0, q1 = p[:n], p[n : 2 * n]
    pm, pc = p[2 * n : 2 * n + npm], p[2 * n + npm :]
    Q = ca.horzcat(q0, X, q1)
    qa, qb = Q[:, :-1], Q[:, 1:]
    f = N * ca.sum2(seg.map(N)(qa, qb, pm))
    E, GR, H = seg_d.map(N)(qa, qb, pm)
    grad = N * ca.vec(GR[n:, : N - 1] + GR[:n, 1:])
    grad_f = ca.Function("nlp_grad_f", [x, p], [N * ca.sum2(E), grad], ["x", "p"],
                         ["f", "grad_f_x"])  # fmt: skip
    lam_f = ca.MX.sym("lam_f")
    rows = N - 1 + subdivisions * N  # constraint blocks of m rows
    lam_g = ca.MX.sym("lam_g", m * rows)
    blocks = [[ca.MX(n, n) for _ in range(N - 1)] for _ in range(N - 1)]
    for j in range(N - 1):
        blocks[j][j] = N * lam_f * (H[n:, 2 * n * j + n : 2 * n * (j + 1)]
                                    + H[:n, 2 * n * (j + 1) : 2 * n * (j + 1) + n])  # fmt: skip
        if j + 1 < N - 1:
            blocks[j][j + 1] = N * lam_f * H[:n, 2 * n * (j + 1) + n : 2 * n * (j + 2)]
    if m:
        # constraints at the interior nodes, then at each subdivision of the segments
        L = ca.reshape(lam_g, m, rows)
        Cn, Jn = clr_j.map(N - 1)(X, pc)
        g_parts, c_parts = [ca.vec(clr.map(N - 1)(X, pc))], [ca.vec(Cn)]
        jrows = [[ca.MX(m, n) for _ in range(N - 1)] for _ in range(rows)]
        for j in range(N - 1):
            jrows[j][j] = Jn[:, j * n : (j + 1) * n]
        if constraint_hessian:
            HN = funcs[4].map(N - 1)(X, pc, L[:, : N - 1])
            for j in range(N - 1):
                blocks[j][j] = blocks[j][j] + HN[:, j * n : (j + 1) * n]
        for i in range(subdivisions):
            # c(m_k), m_k = (1 - t) Q_k + t Q_k+1, depends on X_k-1 (weight 1 - t) and
            # X_k (weight t); Q_0 and Q_N are parameters.
            t = (i + 1) / (subdivisions + 1)
            wts = {-1: 1.0 - t, 0: t}
            M = (1.0 - t) * qa + t * qb
            Cm, Jm = clr_j.map(N)(M, pc)
            g_parts.append(ca.vec(clr.map(N)(M, pc)))
            c_parts.append(ca.vec(Cm))
            first = N - 1 + i * N  # this subdivision's first constraint block
            for k in range(N):
                for dj, wj in wts.items():
                    if 0 <= k + dj < N - 1:
                        jrows[first + k][k + dj] = wj * Jm[:, k * n : (k + 1) * n]
            if constraint_hessian:
                HM = funcs[4].map(N)(M, pc, L[:, first : first + N])
                for k in range(N):
                    hk = HM[:, k * n : (k + 1) * n]
                    for dj, wj in wts.items():
                        if 0 <= k + dj < N - 1:
                            blocks[k + dj][k + dj] = blocks[k + dj][k + dj] + wj * wj * hk
                    if 1 <= k < N - 1:
                        blocks[k - 1][k] = blocks[k - 1][k] + t * (1.0 - t) * hk
        g = ca.vertcat(*g_parts)
        jac_g: ca.Function | None = ca.Function("nlp_jac_g", [x, p], [ca.vertcat(*c_parts), ca.blockcat(jrows)],
                            ["x", "p"], ["g", "jac_g_x"])  # fmt: skip
    else:
        g, jac_g = ca.MX(0, 1), None
    hess = ca.triu(ca.blockcat(blocks))
    hess_l = ca.Function("nlp_hess_l", [x, p, lam_f, lam_g], [hess],
                         ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])  # fmt: skip
    return CollocationNLP(x, p, f, g, grad_f, jac_g, hess_l)
