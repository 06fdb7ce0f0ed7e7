"""Collision spheres fitted to a robot's own collision geometry, made once and cached.

For every link of the file (`geosyn.robots.collision_geometry`; its objects together,
primitives as enclosing polyhedra), the closed surface is cut into triangles with edges
<= `FIT_SPACING` and the link into ``k`` cells (k-means of points filling the link, then
k-centre steps), one sphere per cell; every small triangle goes to the sphere that needs
the least radius to hold its three corners, and each radius is its triangles' farthest
corner plus ``margin``. A ball is convex, so holding a triangle's corners it holds the
triangle: **every point of every collision mesh and primitive lies at least ``margin``
inside a sphere** (tested against the meshes' vertices and dense surface samples). ``k``
(at most `MAX_PER_LINK`) is the smallest count whose spheres reach at most ``excess``
beyond the link, else the one that reaches least; the reach is measured and reported
(`SphereModel.reach`): spheres are conservative, how much is stated.

Self-collision pairs are the link pairs on joints that are neither the same nor parent
and child in the kinematic tree (adjacent links excluded), minus those whose hulls
already overlap at the neutral configuration (the file's own way of overlapping, as an
SRDF's ``Adjacent``/``Default`` entries).

The fit takes seconds for an arm and is cached on disk as JSON under
``$GEOSYN_CACHE_DIR/spheres`` (else ``~/.cache/geosyn/spheres``), keyed by a hash of the
geometry and the settings; `clear_sphere_cache` empties it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from geosyn.core.cache_folder import default_cache_dir, fill_once, read_json, store_json
from geosyn.core.validation import check_float
from geosyn.robots.collision_geometry import (
    CollisionObject,
    collision_objects,
    edge_cuts,
    geometry_digest,
    surface_points,
    surface_triangles,
)
from geosyn.robots.mesh_inside import SolidTest
from geosyn.robots.robot import CollisionSphere, Robot

if TYPE_CHECKING:
    from scipy.spatial import cKDTree

__all__ = [
    "FIT_SPACING",
    "MAX_PER_LINK",
    "FIT_VERSION",
    "SphereModel",
    "clear_sphere_cache",
    "file_spheres",
    "fit_link_spheres",
    "sphere_cache_dir",
]

LLOYD_STEPS = 4
"""k-centre iterations of the sphere fit (each cell's points to their nearest centre,
each centre to its cell's enclosing ball)."""

FIT_SPACING = 0.02
"""Largest triangle edge of the coarser sampling the cells are fitted to [m]."""

MAX_PER_LINK = 8
"""Most spheres fitted to one link."""

FIT_VERSION = 3
"""Part of the cache key: bumped when the fit changes."""


@dataclass(frozen=True)
class SphereModel:
    """Collision spheres of a robot fitted to its file's geometry.

    Attributes:
        spheres: the spheres, link by link.
        links: (len(spheres),) the link each sphere covers.
        margin: every surface point lies at least this far inside a sphere [m].
        excess: the targeted largest reach beyond a link's convex hull [m].
        reach: (len(links),) per link of the file, the largest distance [m] one of its
            spheres reaches beyond the link's convex hull (measured).
        self_pairs: link pairs to check for self-collision (see the module docstring).
        digest: sha256 of the geometry the spheres were fitted to.
        cached: True when read from the disk cache.
    """

    spheres: tuple[CollisionSphere, ...]
    links: tuple[str, ...]
    margin: float
    excess: float
    reach: tuple[float, ...]
    self_pairs: tuple[tuple[str, str], ...]
    digest: str
    cached: bool = False

    @property
    def moving(self) -> tuple[CollisionSphere, ...]:
        """The spheres on moving links: those on the fixed base (``"universe"``) left out,
        since no joint can change their clearance."""
        return tuple(s for s in self.spheres if s.joint != "universe")

    @property
    def max_reach(self) -> float:
        """Largest distance [m] a sphere reaches beyond its link's convex hull."""
        return max(self.reach)


def sphere_cache_dir() -> Path:
    """The sphere cache folder (``spheres`` beside the codegen cache; not created here)."""
    return default_cache_dir().parent / "spheres"


def clear_sphere_cache() -> int:
    """Delete the cached sphere fits (and lock files a killed fit left), the cached
    misses of `geosyn.robots.sphere_cover` and the self pairs' calibrated slack of
    `geosyn.metrics.planning.sampling.cached_slack`; returns how many files were
    removed."""
    folder = sphere_cache_dir()
    removed = 0
    if folder.is_dir():
        patterns = ("spheres_*.json", "spheres_*.lock", "miss_*.json", "slack_*.json")
        for f in [f for pattern in patterns for f in folder.glob(pattern)]:
            f.unlink(missing_ok=True)
            removed += 1
    return removed


def _enclosing_centre(points: np.ndarray, iterations: int = 40) -> np.ndarray:
    """Approximate centre of the smallest ball enclosing ``points`` (Badoiu-Clarkson).

    The farthest point from ``c`` maximises ``|p|^2 - 2 p.c`` (one product per step)."""
    c = 0.5 * (points.min(axis=0) + points.max(axis=0))
    square = np.einsum("ij,ij->i", points, points)
    for i in range(1, iterations + 1):
        far = points[np.argmax(square - 2.0 * (points @ c))]
        c = c + (far - c) / (i + 1)
    return c


def _cells(points: np.ndarray, seeds: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """(k', 3) centres of ``k`` cells of ``points``: k-means of ``seeds`` (points filling
    the link), then k-centre steps (each cell's points to their nearest centre, each
    centre to its cell's enclosing ball)."""
    from scipy.cluster.vq import kmeans2

    C, _ = kmeans2(seeds, k, iter=30, minit="++", seed=rng)
    for _ in range(LLOYD_STEPS):
        label = np.argmin(np.sum((points[:, None, :] - C[None]) ** 2, axis=2), axis=1)
        C = np.array(
            [_enclosing_centre(points[label == i]) for i in range(k) if np.any(label == i)]
        )
    return np.asarray(C)


def subdivide(tris: np.ndarray, spacing: float) -> np.ndarray:
    """(M, 3, 3) the triangles ``tris`` (T, 3, 3) cut into sub-triangles with edges <=
    ``spacing`` [m] (a barycentric grid per triangle, `edge_cuts` ``k`` per edge: the ``k^2``
    sub-triangles of triangle ``t`` follow those of ``t - 1``), computed for all the
    triangles of one ``k`` at once."""
    tris = np.asarray(tris, dtype=np.float64)
    ks = edge_cuts(tris, spacing)
    start = np.concatenate([[0], np.cumsum(ks**2)])
    out = np.empty((int(start[-1]), 3, 3))
    for k in np.unique(ks):
        sel = np.flatnonzero(ks == k)
        t0 = tris[sel, 0][:, None, :]  # (m, 1, 3)
        e1, e2 = ((tris[sel, j] - tris[sel, 0]) / k for j in (1, 2))
        e1, e2 = e1[:, None, :], e2[:, None, :]
        i, j = (a.ravel() for a in np.meshgrid(np.arange(k), np.arange(k), indexing="ij"))
        up, down = i + j < k, i + j < k - 1
        base = t0 + i[None, :, None] * e1 + j[None, :, None] * e2  # (m, k^2, 3)
        b_up, b2 = base[:, up], base[:, down] + e1 + e2
        block = np.concatenate([np.stack([b_up, b_up + e1, b_up + e2], axis=2),
                                np.stack([b2, b2 - e1, b2 - e2], axis=2)], axis=1)  # fmt: skip
        out[start[sel][:, None] + np.arange(k * k)[None]] = block
    return out


def _reach(solid: SolidTest, tree: cKDTree, X: np.ndarray) -> float:
    """The largest distance [m] from a point of ``X`` (K, 3) outside the closed surface
    of ``solid`` to its nearest surface sample (``tree``, a cKDTree of them); 0 when
    every point is inside."""
    d = tree.query(X)[0]
    outside = ~solid.contains(X)
    return float(d[outside].max()) if np.any(outside) else 0.0


def fit_link_spheres(
    tris: np.ndarray, *, excess: float, margin: float, max_spheres: int = MAX_PER_LINK
) -> tuple[np.ndarray, np.ndarray, float]:
    """Spheres covering a link's closed surface ``tris`` (T, 3, 3) [m].

    The surface is cut into triangles with edges <= `FIT_SPACING`; the link into ``k``
    cells (`_cells`, seeded), one sphere per cell; each small triangle goes to the
    sphere that needs the smallest radius to hold its three corners, and each radius is
    its triangles' farthest corner plus ``margin``. A ball is convex: holding a
    triangle's corners, it holds the whole triangle, so every surface point lies at
    least ``margin`` inside a sphere. ``k`` is the smallest count (up to ``max_spheres``)
    whose spheres reach at most ``excess`` beyond the link, else the one that reaches least.

    Args:
        tris: the link's closed surface [m].
        excess: the targeted largest reach of a sphere beyond the link [m], > 0.
        margin: added to every radius [m], >= 0.
        max_spheres: most spheres per link, >= 1.

    Returns:
        ``(centres (k, 3), radii (k,), reach)``; ``reach`` [m] is the largest distance a
        sphere reaches beyond the link (to the nearest corner of the cut surface: at
        most ``FIT_SPACING / sqrt(3)`` above the true distance).
    """
    from scipy.spatial import cKDTree

    small = subdivide(tris, FIT_SPACING)
    corners = small.reshape(-1, 3)
    points = np.unique(np.round(corners, 9), axis=0)
    tree = cKDTree(points)
    u = np.arange(128) + 0.5  # Fibonacci directions on the unit sphere
    z, phi = 1.0 - 2.0 * u / 128, np.pi * (1.0 + 5.0**0.5) * u
    dirs = np.column_stack([np.sqrt(1 - z**2) * np.cos(phi), np.sqrt(1 - z**2) * np.sin(phi), z])
    rng = np.random.default_rng(0)
    # cells of the solid, not of its surface: k-means of points filling it (a surface
    # clustering splits a tube lengthwise, and its spheres bulge out)
    lo, hi = points.min(axis=0), points.max(axis=0)
    axes = [a + (np.arange(12) + 0.5) * (b - a) / 12 for a, b in zip(lo, hi, strict=True)]
    seeds = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    solid = SolidTest(tris)
    seeds = seeds[solid.contains(seeds)]
    if len(seeds) < max_spheres:
        seeds = points
    best: tuple[np.ndarray, np.ndarray, float] = (np.zeros((0, 3)), np.zeros(0), math.inf)
    for k in range(1, max_spheres + 1):
        C = _cells(points, seeds, k, rng)
        # (triangles, spheres): the radius each sphere needs to hold each triangle
        need = np.sqrt(np.sum((small[:, :, None, :] - C[None, None]) ** 2, axis=3)).max(axis=1)
        owner = np.argmin(need, axis=1)
        keep = [i for i in range(len(C)) if np.any(owner == i)]
        R = np.array([float(need[owner == i, i].max()) + margin for i in keep])
        C = C[keep]
        X = (C[:, None, :] + R[:, None, None] * dirs[None]).reshape(-1, 3)
        reach = _reach(solid, tree, X)
        if reach < best[2] - 1e-3:
            best = (C, R, reach)
        if reach <= excess:
            return C, R, reach
    return best


def _self_pairs(robot: Robot, objects: tuple[CollisionObject, ...]) -> list[tuple[str, str]]:
    """Link pairs on non-adjacent joints (see the module docstring), minus pairs whose
    convex hulls already overlap at the neutral configuration."""
    from scipy.spatial import ConvexHull

    model = robot.model
    joint_of = {o.link: o.joint for o in objects}
    parent = {model.names[j]: model.names[model.parents[j]] for j in range(1, model.njoints)}
    data = model.createData()
    pin.forwardKinematics(model, data, robot.neutral())
    pts: dict[str, np.ndarray] = {}
    for o in objects:
        oMj = data.oMi[model.getJointId(o.joint)] if o.joint != "universe" else pin.SE3.Identity()
        P = surface_points(o, 0.05)
        pts[o.link] = np.vstack(
            [pts.get(o.link, np.zeros((0, 3))), P @ oMj.rotation.T + oMj.translation]
        )
    links = sorted(joint_of)
    hulls: dict[str, np.ndarray | None] = {}
    for link in links:
        try:
            hulls[link] = ConvexHull(pts[link]).equations
        except Exception:  # degenerate hull: its pairs kept (checked exactly later)
            hulls[link] = None
    out = []
    for a_i, a in enumerate(links):
        eq, lo, hi = hulls[a], pts[a].min(axis=0), pts[a].max(axis=0)
        for b in links[a_i + 1 :]:
            ja, jb = joint_of[a], joint_of[b]
            if ja == jb or parent.get(ja) == jb or parent.get(jb) == ja:
                continue
            if eq is None:
                out.append((a, b))
                continue
            near = pts[b][np.all((pts[b] >= lo) & (pts[b] <= hi), axis=1)]  # a's box holds its hull
            if not ((near @ eq[:, :3].T + eq[:, 3]).max(axis=1) < 0.0).any():
                out.append((a, b))
    return out


def _cache_path(digest: str, excess: float, margin: float) -> Path:
    key = f"{digest}|{excess!r}|{margin!r}|{FIT_SPACING!r}|{MAX_PER_LINK}|{FIT_VERSION}"
    import hashlib

    return sphere_cache_dir() / f"spheres_{hashlib.sha256(key.encode()).hexdigest()[:24]}.json"


def file_spheres(robot: Robot, *, excess: float = 0.02, margin: float = 0.002) -> SphereModel:
    """Collision spheres of ``robot`` fitted to its file's collision geometry (cached).

    Args:
        robot: a robot loaded from a URDF or MJCF file.
        excess: how far a sphere may reach beyond its link's convex hull before the
            margin [m], > 0 (smaller: tighter spheres, more of them).
        margin: every surface point lies at least this far inside a sphere [m], >= 0.

    Returns:
        The fitted spheres (from the disk cache when the same geometry and settings were
        fitted before).

    Raises:
        RobotFileError: no file or no readable collision geometry (see
            `geosyn.robots.collision_geometry.collision_objects`).
    """
    excess = check_float(excess, "excess", low=1e-4)
    margin = check_float(margin, "margin", low=0.0)
    objects = collision_objects(robot)
    digest = geometry_digest(objects)
    path = _cache_path(digest, excess, margin)
    model = _read_cache(path, margin, excess, digest)
    if model is not None:
        return model
    # One process fits a robot at a time (a sweep's workers on a cold cache): the others
    # wait, then read its file.
    return fill_once(
        path.with_suffix(".lock"),
        lambda: _read_cache(path, margin, excess, digest, warn=False),
        lambda: _fit(robot, objects, margin, excess, digest, path),
    )


def _read_cache(
    path: Path, margin: float, excess: float, digest: str, warn: bool = True
) -> SphereModel | None:
    """The spheres cached at ``path``, or None (missing, or damaged: refitted, and
    warned if ``warn``)."""

    def parse(data: Any) -> SphereModel:
        read = tuple(CollisionSphere(s["joint"], tuple(s["center"]), s["radius"])
                     for s in data["spheres"])  # fmt: skip
        pairs = tuple((a, b) for a, b in data["self_pairs"])
        return SphereModel(read, tuple(data["links"]), margin, excess,
                           tuple(data["reach"]), pairs, digest, True)  # fmt: skip

    return read_json(path, parse, "sphere cache", "fitting again", 3, warn)


def _fit(
    robot: Robot,
    objects: tuple[CollisionObject, ...],
    margin: float,
    excess: float,
    digest: str,
    path: Path,
) -> SphereModel:
    """Fit the spheres of ``objects`` and write them to ``path`` (atomically)."""
    spheres: list[CollisionSphere] = []
    links: list[str] = []
    reaches: list[float] = []
    by_link: dict[str, list[CollisionObject]] = {}
    for o in objects:
        by_link.setdefault(o.link, []).append(o)
    for link, objs in by_link.items():
        tris = np.vstack([surface_triangles(o) for o in objs])
        centres, radii, reach = fit_link_spheres(tris, excess=excess, margin=margin)
        reaches.append(reach)
        for c, r in zip(centres, radii, strict=True):
            spheres.append(
                CollisionSphere(objs[0].joint, (float(c[0]), float(c[1]), float(c[2])), float(r))
            )
            links.append(link)
    pairs = tuple(_self_pairs(robot, objects))
    model = SphereModel(tuple(spheres), tuple(links), margin, excess, tuple(reaches), pairs,
                        digest, False)  # fmt: skip
    record = {
        "robot": robot.name,
        "source_file": robot.source_file,
        "excess": excess,
        "margin": margin,
        "links": links,
        "reach": reaches,
        "self_pairs": [list(p) for p in pairs],
        "spheres": [
            {"joint": s.joint, "center": list(s.center), "radius": s.radius} for s in spheres
        ],
    }
    store_json(path, record, "the sphere cache", 2)  # unwritable: only costs the fit again
    return model
