"""Exact verification of a whole path at once: best-first over the (sample, link, obstacle)
pairs, with the same answer as checking sample by sample.

`geosyn.world.exact_clearance.ExactClearance.path_clearance` checks a path one
configuration at a time (forward kinematics, the links' bounding balls, coal's distance
for each near pair): about 0.13 ms per configuration, 0.04-0.2 s for one Panda plan at
0.005 rad, nearly all of it Python work per configuration rather than coal's distances
(measured). `path_clearance` here checks the same configurations (the same resolution,
joint max-norm, linear between the path's samples) and returns the same smallest
clearance whenever it is below ``near``:

1. forward kinematics of every configuration (one Pinocchio call each), then the bounding
   ball of every link object in every configuration and its signed distance to every
   obstacle, as arrays: lower bounds of every exact distance;
2. coal's exact distance for the pairs whose lower bound is below ``near``, in order of
   that bound, stopping as soon as the next bound is not below the smallest exact distance
   found (every pair left is at least that far).

The pairs measured are a subset of those the configuration-by-configuration check
measures, and none left out can be nearer than the returned minimum.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.world.distance import signed_distance
from geosyn.world.exact_clearance import ExactClearance, PathClearance, checked_configurations

__all__ = [
    "Bounds",
    "Kinematics",
    "PathAids",
    "checked_configurations",
    "configuration_clearances",
    "configuration_gradients",
    "path_clearance",
]


def _frames(exact: ExactClearance, Q: np.ndarray, joints: list[int],
            deadline: float) -> tuple[np.ndarray, np.ndarray] | None:  # fmt: skip
    """((K, J, 3, 3), (K, J, 3)) world rotations and translations of ``joints`` at every
    configuration of ``Q``, or None once ``deadline`` passes."""
    model, data = exact.robot.model, exact.data
    H = np.empty((len(Q), len(joints), 4, 4))
    for i, q in enumerate(Q):
        if i % 64 == 63 and time.perf_counter() > deadline:
            return None
        pin.forwardKinematics(model, data, q)
        for a, j in enumerate(joints):  # joint 0 is the universe: the identity
            H[i, a] = data.oMi[j].homogeneous
    return H[:, :, :3, :3], H[:, :, :3, 3]


Bounds = Callable[[np.ndarray], np.ndarray]
"""``bounds(Q (K, n)) -> (K, L, O)``: lower bounds [m] of the exact distance of each of
``exact``'s L collision objects to each of its O obstacles (e.g. from collision spheres
that cover the objects: `geosyn.metrics.planning.sampling.Sampling.exact_bounds`)."""

Kinematics = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
"""``kinematics(Q (K, n)) -> ((K, J, 3, 3), (K, J, 3))``: world rotations and positions
of every joint by Pinocchio index (0: the universe), as ``data.oMi`` (e.g. in C:
`geosyn.metrics.planning.sphere_native.NativeSphereCheck.joint_frames`)."""


class PathAids(NamedTuple):
    """What makes `path_clearance` faster: the same result where a mesh's convex hull is
    as near as the mesh. ``bounds`` from spheres that cover each mesh bound the mesh, not
    its hull: a pair they leave out may have its hull nearer than the result, never its
    mesh, so the result is then between the hulls' clearance and the meshes' (a UR10
    plan: 7.25 mm reported, its upper arm's hull 0.27 mm into a box, the triangles
    8.66 mm clear of it, measured)."""

    bounds: Bounds | None = None
    kinematics: Kinematics | None = None


def _lower_bounds(exact: ExactClearance, Q: np.ndarray, R: np.ndarray, p: np.ndarray,
                  slot: np.ndarray, bounds: Bounds | None) -> np.ndarray:  # fmt: skip
    """(K, L, O) lower bounds [m] of every exact (configuration, object, obstacle)
    distance: ``bounds`` where it gives one, the objects' bounding balls elsewhere (every
    object when ``bounds`` is None)."""
    L, n_obs = len(exact.geoms), len(exact.obstacles)
    bound = bounds(Q) if bounds is not None else np.full((len(Q), L, n_obs), -math.inf)
    balls = np.flatnonzero(np.isneginf(bound[0]).any(axis=1)) if len(Q) else np.arange(L)
    if balls.size:  # objects without a tighter bound: their bounding balls
        c_local = np.array([exact.balls[k][0] for k in balls])  # in each joint's frame
        radii = np.array([exact.balls[k][1] for k in balls])
        s = slot[balls]
        centres = np.einsum("klab,lb->kla", R[:, s], c_local) + p[:, s]  # (K, B, 3)
        flat = centres.reshape(-1, 3)
        ball = np.stack(
            [signed_distance(ob.shape, flat).reshape(len(Q), -1) - radii for ob in exact.obstacles],
            axis=-1,
        )
        bound[:, balls] = np.maximum(bound[:, balls], ball)
    return bound


def _placements(exact: ExactClearance, Q: np.ndarray, aids: PathAids, deadline: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:  # fmt: skip
    """(R, p, slot): the joints' world rotations (K, J, 3, 3) and positions (K, J, 3) at
    the configurations ``Q`` (K, n) (``aids.kinematics`` when given, else Pinocchio)
    and each collision object's joint's index into them; None once ``deadline``
    passes."""
    if aids.kinematics is not None:
        R, p = aids.kinematics(Q)
        return R, p, np.array(exact.joints)
    joints = sorted(set(exact.joints))
    frames = _frames(exact, Q, joints, deadline)
    if frames is None:
        return None
    return frames[0], frames[1], np.array([joints.index(j) for j in exact.joints])


def _coal_parts(exact: ExactClearance) -> tuple[np.ndarray, np.ndarray, list[tuple[Any, Any]]]:
    """((L, 3, 3), (L, 3), [(geometry, transform)] per obstacle): each collision object's
    placement in its joint's frame, and the obstacles as coal geometries placed in the
    world (what coal's geometry-level ``distance`` takes)."""
    import coal

    R_place = np.array([pl.rotation for pl in exact.placements])
    t_place = np.array([pl.translation for pl in exact.placements])
    others = [
        (ob.geom, coal.Transform3s(ob.pose[:3, :3], ob.pose[:3, 3])) for ob in exact.obstacles
    ]
    return R_place, t_place, others


def _nearest(exact: ExactClearance, Q: np.ndarray, aids: PathAids | None, cap: float,
             witnesses: bool) -> tuple[np.ndarray, list[tuple[int, Any] | None]]:  # fmt: skip
    """`configuration_clearances`' values (K,) and, with ``witnesses``, per configuration
    the nearest pair's (object index, coal ``DistanceResult``) (None where no pair is
    nearer than the cap)."""
    import coal

    Q = np.atleast_2d(np.asarray(Q, dtype=float))
    obstacles = exact.obstacles
    found: list[tuple[int, Any] | None] = [None] * len(Q)
    if not obstacles:
        return np.full(len(Q), math.inf), found
    aids = aids if aids is not None else PathAids()
    placed = _placements(exact, Q, aids, math.inf)
    if placed is None:  # only a deadline stops `_placements`, and none is set
        raise RuntimeError("configuration_clearances: the joint placements were not computed")
    R, p, slot = placed
    bound = _lower_bounds(exact, Q, R, p, slot, aids.bounds).reshape(len(Q), -1)
    order = np.argsort(bound, axis=1, kind="stable")
    ranked = np.take_along_axis(bound, order, axis=1)
    R_place, t_place, others = _coal_parts(exact)
    request = coal.DistanceRequest()
    request.gjk_tolerance = 1e-9
    top = min(cap, exact.near)
    out = np.full(len(Q), top)
    for i in np.flatnonzero(ranked[:, 0] < top):
        low = top
        for index, b in zip(order[i], ranked[i], strict=True):
            if b >= low:
                break  # every pair left is at least this far
            k, o = divmod(int(index), len(obstacles))
            Rj = R[i, slot[k]]
            tf = coal.Transform3s(Rj @ R_place[k], Rj @ t_place[k] + p[i, slot[k]])
            geom, tf_o = others[o]
            result = coal.DistanceResult()
            d = float(coal.distance(exact.geoms[k], tf, geom, tf_o, request, result))
            if d < low:
                low = d
                if witnesses:
                    found[i] = (k, result)
        out[i] = low
    return out, found


def configuration_clearances(exact: ExactClearance, Q: np.ndarray,
                             aids: PathAids | None = None, cap: float = math.inf) -> np.ndarray:  # fmt: skip
    """(K,) the smallest exact clearance [m] at each configuration of ``Q`` (K, n) [rad]
    to the obstacles set on ``exact``, at most ``cap`` [m] and ``exact.near`` (that
    value where no pair is nearer; inf without obstacles): per configuration, coal's
    distance for its pairs in order of their lower bounds (`path_clearance`'s), until
    the next bound is not below the smallest found (or the cap: a caller that needs
    only the clearances below ``cap``, a penalty's, measures fewer pairs). GJK to 1e-9
    (coal's default 1e-6 would dominate a finite difference of 1e-4 rad)."""
    return _nearest(exact, Q, aids, cap, witnesses=False)[0]


def configuration_gradients(exact: ExactClearance, Q: np.ndarray, aids: PathAids | None = None,
                            cap: float = math.inf) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """((K,) `configuration_clearances` [m], (K, n) their gradients [m/rad]) at the
    configurations ``Q`` (K, n) [rad] of a robot with ``nq == nv``: the gradient of the
    nearest pair's distance, ``-normal . v(p)`` with ``p`` coal's witness point on the
    robot's object, ``normal`` coal's unit normal from that object to the obstacle (in
    contact too: the direction that separates them) and ``v(p) = J_lin + omega x (p -
    o_j)`` the point's velocity per joint rate, from Pinocchio's joint Jacobian (world
    aligned) of the object's joint at ``o_j``. Zero where no pair is nearer than
    ``cap`` or ``exact.near`` (the value does not change there) or the object is fixed
    to the world. A minimum over pairs has kinks where two are equally near: there this
    is one side's gradient. One coal pass and one Jacobian per configuration, where
    central differences take 2 n passes."""
    model, data = exact.robot.model, exact.data
    if model.nq != model.nv:
        raise InvalidArgument(
            f"robot: exact clearance gradients need nq == nv, got nq={model.nq}, nv={model.nv}"
        )
    Q = np.atleast_2d(np.asarray(Q, dtype=float))
    c, found = _nearest(exact, Q, aids, cap, witnesses=True)
    g = np.zeros((len(Q), model.nv))
    frame = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    for i, hit in enumerate(found):
        if hit is None or exact.joints[hit[0]] == 0:
            continue
        k, result = hit
        j = exact.joints[k]
        pin.computeJointJacobians(model, data, Q[i])
        J = pin.getJointJacobian(model, data, j, frame)
        normal = np.asarray(result.normal)
        arm = np.asarray(result.getNearestPoint1()) - data.oMi[j].translation
        g[i] = -(normal @ J[:3] + np.cross(arm, normal) @ J[3:])
    return c, g


CHUNK = 64
"""Pairs placed at once (numpy) before their coal distances, in order of their bounds."""


def path_clearance(
    exact: ExactClearance,
    path: np.ndarray,
    resolution: float,
    deadline: float = math.inf,
    aids: PathAids | None = None,
    cap: float = math.inf,
) -> PathClearance:
    """Smallest exact clearance of the linear interpolation of ``path`` (T, n) [rad] to
    the obstacles set on ``exact``, at the configurations of `checked_configurations`.

    Same value as ``exact.path_clearance(path, resolution)`` when it is below
    ``exact.near`` (else at least ``near``); ``inf`` without obstacles; NaN clearance
    when ``time.perf_counter()`` passes ``deadline`` [s] first. ``aids``: the joints'
    placements computed elsewhere (e.g. in C), tighter lower bounds of the pairs'
    distances, used instead of the bounding balls wherever they give one (fewer pairs
    to measure); the same result where a mesh's hull is as near as the mesh, else
    between the hulls' clearance and the meshes' (`PathAids`). ``cap`` [m]: the
    clearance at most this (pairs whose bound is not below it are not measured: a caller
    that asks only whether the path keeps ``cap`` measures far fewer); the same value
    where it is below. O(K (n + L O)) array work plus coal's distance for the pairs whose
    bound is below the result, placed `CHUNK` at a time.
    """
    import coal

    Q = checked_configurations(path, resolution)
    best = PathClearance(math.inf, 0.0, "", -1, len(Q), resolution)
    obstacles = exact.obstacles
    if not obstacles:
        return best
    aids = aids if aids is not None else PathAids()
    if time.perf_counter() > deadline:  # not begun: its placements alone cost 1-10 ms
        return best._replace(clearance=math.nan, checked=0)
    placed = _placements(exact, Q, aids, deadline)
    if placed is None:
        return best._replace(clearance=math.nan, checked=0)
    R, p, slot = placed
    parts = []  # the bounds, `CHUNK` * 4 configurations at a time (1-3 ms each)
    for a in range(0, len(Q), 4 * CHUNK):
        if time.perf_counter() > deadline:
            return best._replace(clearance=math.nan, checked=0)
        b = slice(a, a + 4 * CHUNK)
        parts.append(_lower_bounds(exact, Q[b], R[b], p[b], slot, aids.bounds))
    bound = np.concatenate(parts).ravel()
    top = min(cap, exact.near)
    near = np.flatnonzero(bound < top)
    order = near[np.argsort(bound[near], kind="stable")]
    sorted_bound = bound[order]
    at, obj, obs = np.unravel_index(order, (len(Q), len(exact.geoms), len(obstacles)))
    R_place, t_place, others = _coal_parts(exact)
    low, request = top, exact.request
    tf, geoms = coal.Transform3s(), exact.geoms  # placed anew for each pair
    hit: tuple[int, int, int] | None = None
    for start in range(0, len(order), CHUNK):
        if sorted_bound[start] >= low:
            break  # every pair left is at least this far
        if time.perf_counter() > deadline:  # before each chunk, the first too
            return best._replace(clearance=math.nan)
        i, k, o = at[start : start + CHUNK], obj[start : start + CHUNK], obs[start : start + CHUNK]
        Rj, pj = R[i, slot[k]], p[i, slot[k]]
        Rg = Rj @ R_place[k]  # (C, 3, 3) world placements of the objects
        tg = np.einsum("cab,cb->ca", Rj, t_place[k]) + pj
        chunk = zip(sorted_bound[start : start + CHUNK].tolist(), i.tolist(), k.tolist(),
                    o.tolist(), Rg, tg, strict=True)  # fmt: skip
        for m, (b, ii, kk, oo, Rm, tm) in enumerate(chunk):
            if b >= low:
                break
            if m % 16 == 15 and time.perf_counter() > deadline:  # 16 pairs: 0.3-2 ms
                return best._replace(clearance=math.nan)
            tf.setRotation(Rm)
            tf.setTranslation(tm)
            geom, tf_o = others[oo]
            # a new DistanceResult per pair: one reused across pairs returned penetration
            # depths off by up to 21 mm (coal 3.0.3: 80 of 387 Panda path minima, measured)
            d = coal.distance(geoms[kk], tf, geom, tf_o, request, coal.DistanceResult())
            if d < low:
                low, hit = d, (ii, kk, oo)
    if hit is None:  # no pair nearer than ``near`` (or the cap) anywhere
        return best._replace(clearance=top)
    return best._replace(clearance=low, where=hit[0] / max(len(Q) - 1, 1),
                         link=exact.objects[hit[1]].link, obstacle=hit[2])  # fmt: skip
