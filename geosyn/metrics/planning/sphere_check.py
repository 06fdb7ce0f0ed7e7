"""`SphereCheck`: the planner's collision spheres against the obstacles, many
configurations at once, for sampling (RRT-Connect, shortcuts).

The collocation's clearance function (`Collocation.node_clearances`, a CasADi SX function
interpreted per configuration) costs about 70 us per configuration on the Panda with 8
obstacle slots (measured), most of a sampling planner's time. Here one Pinocchio forward
kinematics per configuration places every sphere (centre in its joint's frame) and the
signed distances (`geosyn.world.distance.signed_distance`; all boxes in one array
operation) to the active obstacles are array work over all spheres and configurations. The distances are the exact sphere
clearances (no smooth minimum), of the same spheres.

Self-collision (`set_self_pairs`): the distances between the spheres of the file's
self-collision link pairs (`geosyn.robots.collision_spheres.SphereModel.self_pairs`),
per link pair, as array work too. The fitted spheres cover every point of their link's
collision geometry, so a pair's sphere distance is a lower bound of its exact distance
(`geosyn.metrics.planning.self_collision`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.metrics.planning.rrt import segment_points
from geosyn.robots.robot import CollisionSphere, Robot
from geosyn.world.distance import signed_distance
from geosyn.world.shapes import Box, Shape

__all__ = ["Ends", "Frames", "Raises", "SphereCheck"]

Frames = tuple[np.ndarray, np.ndarray]
"""((K, J, 3, 3), (K, J, 3)): world rotations and positions of the sphere joints."""


class Ends(NamedTuple):
    """A query's ends as `SphereCheck.set_ends` keeps them: the ends E (k, n) [rad], their
    clearances (k,) [m] and the margin's slope [m/rad], the self pairs' sphere distances
    there D (k, P) [m] and the floors' slope [m/rad]."""

    E: np.ndarray
    clear: np.ndarray
    slope: float
    D: np.ndarray
    floor_slope: float

    @classmethod
    def none(cls, nq: int, pairs: int) -> Ends:
        """No ends (a robot of ``nq`` coordinates, ``pairs`` self pairs)."""
        return cls(np.zeros((0, nq)), np.zeros(0), 0.0, np.zeros((0, pairs)), 0.0)


class Raises(NamedTuple):
    """Local raises of self floors (`SphereCheck.set_raises`): within ``radius[r]`` [rad]
    (joint-space 2-norm) of ``at[r]`` (n,) [rad], self pair ``pair[r]``'s floor is at least
    ``floor[r]`` [m]; R raises."""

    pair: np.ndarray
    at: np.ndarray
    radius: np.ndarray
    floor: np.ndarray

    @classmethod
    def none(cls, nq: int) -> Raises:
        """No raises (a robot of ``nq`` coordinates)."""
        return cls(np.zeros(0, dtype=int), np.zeros((0, nq)), np.zeros(0), np.zeros(0))


class SphereCheck:
    """Smallest clearance [m] of a robot's collision spheres to obstacles.

    Args:
        robot: the robot (its Pinocchio model places the spheres).
        spheres: the spheres, each on a joint of ``robot`` (``"universe"``: the world).

    Allocates its Pinocchio data once; `clearances` allocates only its result arrays.

    Attributes:
        ends: the query's ends as `set_ends` last set them (`Ends`; read it, set them
            with `set_ends`).
        raises: the local raises of the self floors (`Raises`; set with `set_raises`).
    """

    def __init__(self, robot: Robot, spheres: Sequence[CollisionSphere]) -> None:
        self.robot = robot
        ids = [robot.joint_id(s.joint) if s.joint != "universe" else 0 for s in spheres]
        self._ids = ids
        self._joints = sorted(set(ids))
        self._slot = np.array([self._joints.index(j) for j in ids], dtype=int)
        self._centre = np.array([s.center for s in spheres], dtype=float).reshape(-1, 3)
        self._radius = np.array([s.radius for s in spheres], dtype=float)
        self._data = robot.model.createData()
        self.obstacles: tuple[Shape, ...] = ()
        self.self_pairs: tuple[tuple[str, str], ...] = ()
        self.self_slack = np.zeros(0)
        self._self_floor = np.zeros(0)
        self.ends = Ends.none(robot.model.nq, 0)
        self.raises = Raises.none(robot.model.nq)

    def set_self_pairs(self, spheres: Sequence[CollisionSphere], links: Sequence[str],
                       pairs: Sequence[tuple[str, str]]) -> None:  # fmt: skip
        """Check the link ``pairs`` for self-collision on ``spheres`` (each covering the
        link of the same index of ``links``; pairs without spheres are left out).
        Allocates; the floors of `self_valid` are reset to 0, and a query's ends
        (`set_ends`) and raises (`set_raises`) dropped."""
        ids = [self.robot.joint_id(s.joint) if s.joint != "universe" else 0 for s in spheres]
        self._joints = sorted(set(self._ids) | set(ids))  # one kinematics for both
        self._slot = np.array([self._joints.index(j) for j in self._ids], dtype=int)
        self._s_slot = np.array([self._joints.index(j) for j in ids], dtype=int)
        self._s_centre = np.array([s.center for s in spheres], dtype=float).reshape(-1, 3)
        self._s_radius = np.array([s.radius for s in spheres], dtype=float)
        first: list[int] = []
        second: list[int] = []
        start: list[int] = []
        kept: list[tuple[str, str]] = []
        for a, b in pairs:
            ia = [k for k, link in enumerate(links) if link == a]
            ib = [k for k, link in enumerate(links) if link == b]
            if ia and ib:
                start.append(len(first))
                kept.append((a, b))
                first += [i for i in ia for _ in ib]
                second += [j for _ in ia for j in ib]
        self.self_pairs = tuple(kept)
        self.self_slack = np.zeros(len(kept))  # [m] each floor at most minus it (`set_ends`)
        self._I, self._J = np.array(first, dtype=int), np.array(second, dtype=int)
        self._start = np.array(start, dtype=int)
        self._self_floor = np.zeros(len(kept))
        self.ends = Ends.none(self.robot.model.nq, len(kept))
        self.raises = Raises.none(self.robot.model.nq)

    def frames(self, Q: np.ndarray) -> Frames:
        """((K, J, 3, 3), (K, J, 3)) world rotations and positions of the joints carrying
        spheres at each configuration of ``Q`` (K, n) [rad] (one Pinocchio forward
        kinematics each), to share between `clearances` and `self_clearances`."""
        Q = np.asarray(Q, dtype=float).reshape(-1, self.robot.model.nq)
        model, data, joints = self.robot.model, self._data, self._joints
        H = np.empty((len(Q), len(joints), 4, 4))
        for i, q in enumerate(Q):
            pin.forwardKinematics(model, data, q)
            for a, j in enumerate(joints):  # joint 0 is the universe: the identity
                H[i, a] = data.oMi[j].homogeneous
        return H[:, :, :3, :3], H[:, :, :3, 3]

    def self_clearances(self, Q: np.ndarray, frames: Frames | None = None) -> np.ndarray:
        """(K, P) smallest sphere distance [m] of each of the ``self_pairs`` (P) at each
        configuration of ``Q`` (K, n) [rad] (``frames``: theirs, from `frames`): lower
        bounds of the exact distances."""
        Q = np.asarray(Q, dtype=float).reshape(-1, self.robot.model.nq)
        if not self.self_pairs:
            return np.full((len(Q), 0), math.inf)
        R, p = self.frames(Q) if frames is None else frames
        c = np.einsum("ksab,sb->ksa", R[:, self._s_slot], self._s_centre) + p[:, self._s_slot]
        r = self._s_radius
        d = np.linalg.norm(c[:, self._I] - c[:, self._J], axis=2) - r[self._I] - r[self._J]
        return np.asarray(np.minimum.reduceat(d, self._start, axis=1))

    def set_ends(self, ends: Sequence[np.ndarray], clearances: Sequence[float] | np.ndarray,
                 slope: float, floor_slope: float = 0.0) -> None:  # fmt: skip
        """A query's ``ends`` (at most 2, e.g. start and goal, (n,) [rad] each), near which
        `valid` asks for less:

        - the margin in force at ``q`` is ``min(margin, c_e + slope |q - e|)`` over the
          ends ``e`` with their ``clearances`` ``c_e`` [m] (``slope`` [m/rad]; `margins`);
        - each self pair's floor is ``min(0, -self_slack, d_e + floor_slope |q - e|)``,
          ``d_e`` the pair's sphere distance at ``e`` (``floor_slope`` [m/rad], 0: lowered
          everywhere; `self_floors`). The spheres reach beyond the links: a query whose
          ends are exactly clear but sphere-close keeps them valid, without letting the
          pair overlap as deeply far from them.

        No ends: the margin and the floors ``min(0, -self_slack)`` everywhere. One set of
        ends for both (the C check measures ``|q - e|`` once per configuration).

        Raises:
            InvalidArgument: more than 2 ends, or not one clearance per end.
        """
        n = self.robot.model.nq
        E = np.asarray(ends, dtype=float).reshape(-1, n)
        c = np.asarray(clearances, dtype=float).reshape(-1)
        if len(E) > 2 or len(c) != len(E):
            raise InvalidArgument(
                f"set_ends: at most 2 ends (n,) = ({n},) with one clearance each, got "
                f"{len(E)} end(s) and {len(c)} clearance(s)"
            )
        self._self_floor = np.minimum(-np.asarray(self.self_slack, dtype=float), 0.0)
        self.ends = Ends(E, c, float(slope), self.self_clearances(E), float(floor_slope))

    def set_raises(self, raises: Raises) -> None:
        """Local raises of the self floors (`Raises`; they replace earlier ones), applied
        before the ends' lowering (`self_floors`): an end stays valid.

        Raises:
            InvalidArgument: a pair index outside the self pairs, or other shapes.
        """
        n, P, R = self.robot.model.nq, len(self.self_pairs), len(raises.pair)
        pair = np.asarray(raises.pair, dtype=int).reshape(-1)
        shapes = (np.shape(raises.at), np.shape(raises.radius), np.shape(raises.floor))
        if shapes != ((R, n), (R,), (R,)) or np.any((pair < 0) | (pair >= P)):
            raise InvalidArgument(
                f"set_raises: pair (R,) in [0, {P}), at (R, {n}), radius (R,), floor (R,); "
                f"got pairs {pair.tolist()} and shapes {shapes}"
            )
        self.raises = Raises(pair, *(np.array(a, dtype=float) for a in raises[1:]))

    def self_floors(self, Q: np.ndarray) -> np.ndarray:
        """(K, P) the floor of each self pair in force at each configuration of ``Q``
        (K, n) [rad]: raised where `set_raises` says, then lowered near the ends
        (`set_ends`)."""
        Q = np.asarray(Q, dtype=float).reshape(-1, self.robot.model.nq)
        out = np.tile(self._self_floor, (len(Q), 1))
        for k, at, radius, floor in zip(*self.raises, strict=True):
            inside = np.linalg.norm(Q - at, axis=1) < radius
            out[inside, k] = np.maximum(out[inside, k], floor)
        ends = self.ends
        for e, d in zip(ends.E, ends.D, strict=True):
            away = np.linalg.norm(Q - e, axis=1)[:, None]
            out = np.minimum(out, d[None, :] + ends.floor_slope * away)
        return np.asarray(out)

    def self_valid(self, Q: np.ndarray, frames: Frames | None = None) -> np.ndarray:
        """(K,) True where no self pair's sphere distance is below its floor
        (`self_floors`; ``frames`` as in `self_clearances`)."""
        if not self.self_pairs:
            return np.ones(len(np.asarray(Q).reshape(-1, self.robot.model.nq)), dtype=bool)
        return np.asarray(np.all(self.self_clearances(Q, frames) >= self.self_floors(Q), axis=1))

    def margins(self, Q: np.ndarray, margin: float) -> np.ndarray:
        """(K,) the margin in force [m] at each configuration of ``Q`` (K, n) [rad]
        (`set_ends`)."""
        ends = self.ends
        Q = np.asarray(Q, dtype=float).reshape(-1, self.robot.model.nq)
        out = np.full(len(Q), float(margin))
        for e, ce in zip(ends.E, ends.clear, strict=True):
            out = np.minimum(out, ce + ends.slope * np.linalg.norm(Q - e, axis=1))
        return out

    def valid(self, Q: np.ndarray, margin: float) -> np.ndarray:
        """(K,) True where the configurations ``Q`` (K, n) [rad] keep clearance >= the
        margin in force (``margin`` [m], lower near a query's ends: `margins`) to the
        obstacles and no self pair is below its floor (`self_valid`)."""
        Q = np.asarray(Q, dtype=float).reshape(-1, self.robot.model.nq)
        R, p = self.frames(Q)
        ok = self.clearances(Q, (R, p)) >= self.margins(Q, margin)
        if self.self_pairs and ok.any():
            ok[ok] = self.self_valid(Q[ok], (R[ok], p[ok]))
        return ok

    def all_valid(self, Q: np.ndarray, margin: float) -> bool:
        """Whether every configuration of ``Q`` (K, n) [rad] is valid (`valid`)."""
        return bool(np.all(self.valid(Q, margin)))

    def segment_valid(self, a: np.ndarray, b: np.ndarray, resolution: float,
                      margin: float) -> bool:  # fmt: skip
        """Whether the segment ``a`` -> ``b`` (n,) [rad] is valid at the points
        ``a + (i / k) (b - a)``, i = 1 .. k, ``k = max(1, ceil(|b - a| / resolution))``."""
        return self.all_valid(segment_points(a, b, resolution), margin)

    def path_valid(self, X: np.ndarray, resolution: float, margin: float) -> bool:
        """Whether every segment of the path ``X`` (T, n) [rad] is valid (`segment_valid`;
        ``X[0]`` itself not checked), stopping at the first invalid one."""
        X = np.asarray(X, dtype=float)
        return all(self.segment_valid(a, b, resolution, margin)
                   for a, b in zip(X[:-1], X[1:], strict=True))  # fmt: skip

    def set_obstacles(self, obstacles: Sequence[Shape]) -> None:
        """Replace the obstacles (shapes of `geosyn.world`, already checked)."""
        self.obstacles = tuple(obstacles)
        boxes = [ob for ob in self.obstacles if isinstance(ob, Box)]
        self._others = [ob for ob in self.obstacles if not isinstance(ob, Box)]
        self._box_centre = np.array([b.center for b in boxes], dtype=float).reshape(-1, 3)
        self._box_rotation = np.array([b.rotation for b in boxes], dtype=float).reshape(-1, 3, 3)
        self._box_half = np.array([b.half_extents for b in boxes], dtype=float).reshape(-1, 3)

    def _box_distances(self, points: np.ndarray) -> np.ndarray:
        """(P,) smallest signed distance of ``points`` (P, 3) [m] to the boxes (the
        formula of `geosyn.world.distance`, every box at once)."""
        rel = points[:, None, :] - self._box_centre[None]  # (P, B, 3)
        local = np.abs(np.einsum("pba,bac->pbc", rel, self._box_rotation)) - self._box_half
        outside = np.linalg.norm(np.maximum(local, 0.0), axis=2)
        inside = np.minimum(local.max(axis=2), 0.0)
        return np.asarray((outside + inside).min(axis=1))

    def clearances(self, Q: np.ndarray, frames: Frames | None = None) -> np.ndarray:
        """(K,) smallest sphere-obstacle signed distance [m] at each configuration of
        ``Q`` (K, n) [rad] (``frames``: theirs, from `frames`); inf without obstacles
        or spheres. O(K (n + S O))."""
        Q = np.asarray(Q, dtype=float).reshape(-1, self.robot.model.nq)
        if not self.obstacles or not self._radius.size:
            return np.full(len(Q), math.inf)
        R, p = self.frames(Q) if frames is None else frames
        centres = np.einsum("ksab,sb->ksa", R[:, self._slot], self._centre) + p[:, self._slot]
        flat = centres.reshape(-1, 3)
        nearest = np.full(len(flat), math.inf)  # (K S,) to the nearest obstacle
        if len(self._box_half):
            nearest = self._box_distances(flat)
        for ob in self._others:
            nearest = np.minimum(nearest, signed_distance(ob, flat))
        return np.asarray((nearest.reshape(len(Q), -1) - self._radius).min(axis=1))

    @property
    def gradients(self) -> Callable[[np.ndarray], np.ndarray] | None:
        """``(K, n) -> (K, n)`` the gradients [m/rad] of `clearances`, when this check
        computes them (the C check: `NativeSphereCheck.clearance_gradients`); None here:
        a relaxation on these clearances takes central differences."""
        return None
