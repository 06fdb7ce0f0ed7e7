"""`NativeSphereCheck`: `SphereCheck` evaluated in C, for the planner's sampling.

A sampling planner spends its time in the validity check: the numpy `SphereCheck` costs
about 150 us per configuration on the Panda (one Pinocchio forward kinematics from
Python per configuration, then array work; measured on the benchmark scenes), so
RRT-Connect grows only tens of nodes in 0.2 s. ``native/geosyn_spheres.c`` does the same
computation in C: forward kinematics of the robot's revolute and prismatic joints (the
tree, placements and axes of its Pinocchio model), the spheres' world centres, the exact
signed distances of `geosyn.world.distance` to every obstacle shape, the self pairs'
sphere distances and the validity rule. It is robot-independent (the robot is data,
passed at creation), compiled once per machine through the codegen cache
(`geosyn.core.codegen.compile_shared`, verified before it is loaded) and called through
``ctypes``.

`sphere_check` returns the native check when it can and the numpy one otherwise, saying
why (a joint type other than revolute or prismatic, no C compiler).
"""

from __future__ import annotations

import ctypes
import functools
import math
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from geosyn.core.codegen import CodegenError, compile_shared
from geosyn.core.errors import InvalidArgument
from geosyn.metrics.planning.rrt import DYNAMIC_DOMAIN, RRT_STEP, Near, check_domain, check_near
from geosyn.metrics.planning.sphere_check import Frames, Raises, SphereCheck
from geosyn.robots.robot import CollisionSphere, Robot
from geosyn.world.shapes import Box, Capsule, Cylinder, HalfSpace, Shape, Sphere

__all__ = ["C_SOURCE", "NativeSphereCheck", "joint_table", "sphere_check"]

C_SOURCE = Path(__file__).resolve().parent / "native" / "geosyn_spheres.c"
"""The C source of the check (package data)."""
_OBSTACLE = 16  # numbers per obstacle, as GS_OBSTACLE in the C source
_P = ctypes.c_void_p
_I = ctypes.c_int
_D = ctypes.c_double
RRT_SLICE = 0.05
"""Longest C call of `NativeSphereCheck.rrt_connect` [s]: Python's signal handlers (a
SIGTERM) run between slices."""


@functools.cache
def _library() -> ctypes.CDLL:
    """The compiled check, loaded once per process (compiled once per machine)."""
    path = compile_shared("geosyn_spheres", C_SOURCE.read_text(), flags=("-O3",))
    lib = ctypes.CDLL(str(path))
    signatures = {
        "geosyn_spheres_create": (_P, [_I, _I, _P, _P, _P, _P, _P]),
        "geosyn_spheres_free": (None, [_P]),
        "geosyn_spheres_set_spheres": (_I, [_P, _I, _I, _P, _P, _P]),
        "geosyn_spheres_set_pairs": (_I, [_P, _I, _P, _P, _I, _P, _P]),
        "geosyn_spheres_set_obstacles": (_I, [_P, _I, _P, _P]),
        "geosyn_spheres_clearances": (None, [_P, _P, _I, _P]),
        "geosyn_spheres_clearance_gradients": (None, [_P, _P, _I, _P, _P]),
        "geosyn_spheres_self_clearances": (None, [_P, _P, _I, _P]),
        "geosyn_spheres_obstacle_distances": (None, [_P, _P, _I, _P]),
        "geosyn_spheres_group_distances": (None, [_P, _P, _I, _P, _I, _P]),
        "geosyn_spheres_frames": (None, [_P, _P, _I, _P, _P]),
        "geosyn_spheres_set_ends": (_I, [_P, _I, _P, _P, _D, _P, _P, _D]),
        "geosyn_spheres_set_raises": (_I, [_P, _I, _P, _P, _P, _P]),
        "geosyn_spheres_valid": (_I, [_P, _P, _I, _D, _I, _I, _P]),
        "geosyn_spheres_segment_valid": (_I, [_P, _P, _P, _D, _D, _I]),
        "geosyn_spheres_path_valid": (_I, [_P, _P, _I, _D, _D, _I]),
        "geosyn_spheres_rrt_connect": (
            _I,
            [_P] * 5 + [_D] * 4 + [_I] + [_P] * 7 + [_I, _P, _P, _D, _P, _I, _P],
        ),
    }
    for name, (res, args) in signatures.items():
        fun = getattr(lib, name)
        fun.restype, fun.argtypes = res, args
    return lib


NATIVE_MAX_NQ = 64
"""Most coordinates of a robot the C check takes (its segment and ramp buffers)."""


def _verdict(code: int) -> bool:
    """A C segment check's answer: 1 valid, 0 not; -1 (more coordinates than its buffers,
    `NATIVE_MAX_NQ`: `joint_table` refuses such robots first) raised, never read as valid."""
    if code < 0:
        raise InvalidArgument(f"the C sphere check takes at most {NATIVE_MAX_NQ} coordinates")
    return bool(code)


def joint_table(robot: Robot) -> tuple[np.ndarray, ...] | str:
    """The kinematic tree of ``robot``'s Pinocchio model as the C check reads it:
    ``(parent (J,), kind (J,) 0 revolute / 1 prismatic, q index (J,), axis (J, 3),
    placement (J, 12): rotation row-major then translation [m])`` for its J joints
    (the universe left out; parent -1: the world), or the reason it cannot (a joint
    that is not a one-coordinate revolute or prismatic joint, or more than
    `NATIVE_MAX_NQ` coordinates)."""
    model = robot.model
    if model.nq > NATIVE_MAX_NQ:
        return f"{model.nq} coordinates, more than the C check's {NATIVE_MAX_NQ}"
    J = model.njoints - 1
    parent, kind, iq = np.zeros(J, np.intc), np.zeros(J, np.intc), np.zeros(J, np.intc)
    axis, place = np.zeros((J, 3)), np.zeros((J, 12))
    q0 = np.zeros(model.nq)
    for j in range(1, model.njoints):
        jm = model.joints[j]
        if jm.nq != 1 or jm.nv != 1:
            return f"joint {model.names[j]!r} ({jm.shortname()}) is not a one-coordinate joint"
        data = jm.createData()
        jm.calc(data, q0)
        S = np.asarray(data.S, dtype=float).reshape(6)
        linear, angular = S[:3], S[3:]
        if np.linalg.norm(linear) < 1e-12 and abs(np.linalg.norm(angular) - 1.0) < 1e-9:
            kind[j - 1], axis[j - 1] = 0, angular
        elif np.linalg.norm(angular) < 1e-12 and abs(np.linalg.norm(linear) - 1.0) < 1e-9:
            kind[j - 1], axis[j - 1] = 1, linear
        else:
            return f"joint {model.names[j]!r} ({jm.shortname()}) is neither revolute nor prismatic"
        parent[j - 1], iq[j - 1] = model.parents[j] - 1, jm.idx_q
        M = model.jointPlacements[j]
        place[j - 1] = np.concatenate([np.asarray(M.rotation).ravel(), M.translation])
    return parent, kind, iq, axis, place


def _obstacle_row(shape: Shape) -> tuple[int, np.ndarray]:
    """(kind, (16,) numbers) of one obstacle in the C layout (geosyn_spheres.c)."""
    row = np.zeros(_OBSTACLE)
    if isinstance(shape, Sphere):
        row[:3], row[15] = shape.center, shape.radius
        return 0, row
    if isinstance(shape, Box):
        row[:3], row[3:12], row[12:15] = shape.center, np.ravel(shape.rotation), shape.half_extents
        return 1, row
    if isinstance(shape, Capsule):
        row[:3], row[3:6], row[15] = shape.p0, shape.p1, shape.radius
        return 2, row
    if isinstance(shape, Cylinder):
        row[:3], row[3:12] = shape.center, np.ravel(shape.rotation)
        row[12], row[13] = shape.radius, shape.half_length
        return 3, row
    if isinstance(shape, HalfSpace):
        row[:3], row[3] = shape.normal, shape.offset
        return 4, row
    raise TypeError(f"no C distance for {type(shape).__name__}")  # shapes are checked before


def _address(a: np.ndarray) -> int:
    return int(a.ctypes.data)


class NativeSphereCheck(SphereCheck):
    """`SphereCheck` in C (module docstring): the same clearances, self-clearances and
    validity, to round-off (the kinematics and distances are summed in another order).

    Args:
        robot: the robot; every joint of its model revolute or prismatic (`joint_table`).
        spheres: the spheres, each on a joint of ``robot`` (``"universe"``: the world).

    Raises:
        CodegenError: the C check could not be compiled (no compiler).
        InvalidArgument: a joint the C kinematics does not model (`joint_table`'s reason).
    """

    def __init__(self, robot: Robot, spheres: Sequence[CollisionSphere]) -> None:
        super().__init__(robot, spheres)
        table = joint_table(robot)
        if isinstance(table, str):
            raise InvalidArgument(
                f"robot {robot.name!r}: {table} (the C check takes "
                "revolute and prismatic joints of one coordinate)"
            )
        lib = _library()
        self._lib = lib
        self._table = [np.ascontiguousarray(a) for a in table]
        parent, kind, iq, axis, place = self._table
        self._handle = lib.geosyn_spheres_create(
            robot.model.nq, len(parent), *(_address(a) for a in (parent, kind, iq, axis, place))
        )
        if not self._handle:
            raise MemoryError("geosyn_spheres_create: out of memory")
        self._finalize = _Finalizer(lib, self._handle)
        self._push_spheres(0, [s.joint for s in spheres], self._centre, self._radius)
        self._n_pairs = 0
        self._valid_out = np.zeros(0, dtype=np.uint8)

    def _push_spheres(self, which: int, joints: Sequence[str], centre: np.ndarray,
                      radius: np.ndarray) -> None:  # fmt: skip
        ids = np.array([self.robot.joint_id(j) - 1 if j != "universe" else -1 for j in joints],
                       dtype=np.intc)  # fmt: skip
        c = np.ascontiguousarray(centre, dtype=float).reshape(-1, 3)
        r = np.ascontiguousarray(radius, dtype=float)
        if self._lib.geosyn_spheres_set_spheres(self._handle, which, len(ids), _address(ids),
                                                _address(c), _address(r)):  # fmt: skip
            raise MemoryError("geosyn_spheres_set_spheres: out of memory")

    def set_self_pairs(self, spheres: Sequence[CollisionSphere], links: Sequence[str],
                       pairs: Sequence[tuple[str, str]]) -> None:  # fmt: skip
        """As `SphereCheck.set_self_pairs`; also hands the pairs to C. Allocates."""
        super().set_self_pairs(spheres, links, pairs)
        self._push_spheres(1, [s.joint for s in spheres], self._s_centre, self._s_radius)
        first = np.ascontiguousarray(self._I, dtype=np.intc)
        second = np.ascontiguousarray(self._J, dtype=np.intc)
        start = np.ascontiguousarray(np.append(self._start, len(first)), dtype=np.intc)
        self._n_pairs = len(self.self_pairs)
        floor = np.ascontiguousarray(self._self_floor, dtype=float)
        if self._lib.geosyn_spheres_set_pairs(self._handle, len(first), _address(first),
                                              _address(second), self._n_pairs, _address(start),
                                              _address(floor)):  # fmt: skip
            raise MemoryError("geosyn_spheres_set_pairs: out of memory")

    def set_ends(self, ends: Sequence[np.ndarray], clearances: Sequence[float] | np.ndarray,
                 slope: float, floor_slope: float = 0.0) -> None:  # fmt: skip
        """As `SphereCheck.set_ends`; also hands the ends, margins and floors to C."""
        super().set_ends(ends, clearances, slope, floor_slope)
        E, c, D = (np.ascontiguousarray(a) for a in (self.ends.E, self.ends.clear, self.ends.D))
        floor = np.ascontiguousarray(self._self_floor, dtype=float)
        if self._lib.geosyn_spheres_set_ends(self._handle, len(E), _address(E), _address(c),
                                             float(slope), _address(floor), _address(D),
                                             float(floor_slope)):  # fmt: skip
            raise InvalidArgument(f"set_ends: at most 2 ends and {NATIVE_MAX_NQ} coordinates")

    def set_raises(self, raises: Raises) -> None:
        """As `SphereCheck.set_raises`; also hands them to C."""
        super().set_raises(raises)
        pair = np.ascontiguousarray(self.raises.pair, dtype=np.intc)
        at, radius, floor = (np.ascontiguousarray(a) for a in self.raises[1:])
        if self._lib.geosyn_spheres_set_raises(self._handle, len(pair), _address(pair),
                                               _address(at), _address(radius), _address(floor)):  # fmt: skip
            raise MemoryError("geosyn_spheres_set_raises: out of memory")

    def set_obstacles(self, obstacles: Sequence[Shape]) -> None:
        """As `SphereCheck.set_obstacles` (the same obstacles again: nothing to do)."""
        obstacles = tuple(obstacles)
        if len(obstacles) == len(self.obstacles) and all(
            a is b for a, b in zip(obstacles, self.obstacles, strict=True)
        ) and hasattr(self, "_okind"):  # fmt: skip
            return
        super().set_obstacles(obstacles)
        rows = [_obstacle_row(ob) for ob in obstacles]
        self._okind = np.array([k for k, _ in rows], dtype=np.intc)
        self._opar = np.ascontiguousarray(np.array([r for _, r in rows]).reshape(-1, _OBSTACLE))
        if self._lib.geosyn_spheres_set_obstacles(self._handle, len(rows), _address(self._okind),
                                                  _address(self._opar)):  # fmt: skip
            raise MemoryError("geosyn_spheres_set_obstacles: out of memory")

    def _configurations(self, Q: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(np.asarray(Q, dtype=float).reshape(-1, self.robot.model.nq))

    def clearances(self, Q: np.ndarray, frames: Frames | None = None) -> np.ndarray:
        """As `SphereCheck.clearances` (``frames`` is not needed). O(K (n + S O))."""
        Q = self._configurations(Q)
        if not self.obstacles or not self._radius.size:
            return np.full(len(Q), math.inf)
        out = np.empty(len(Q))
        self._lib.geosyn_spheres_clearances(self._handle, _address(Q), len(Q), _address(out))
        return out

    def clearance_gradients(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """((K,) `clearances` [m], (K, n) their gradients [m/rad]) at ``Q`` (K, n) [rad]:
        the nearest sphere-obstacle pair's, its shape's distance gradient at the sphere's
        centre times the centre's joint Jacobian (one side's at a kink of the minimum;
        zero without obstacles or spheres). O(K (n + S O))."""
        Q = self._configurations(Q)
        out, grad = np.full(len(Q), math.inf), np.zeros(Q.shape)
        if self.obstacles and self._radius.size:
            self._lib.geosyn_spheres_clearance_gradients(self._handle, _address(Q), len(Q),
                                                         _address(out), _address(grad))  # fmt: skip
        return out, grad

    @property
    def gradients(self) -> Callable[[np.ndarray], np.ndarray]:
        """The gradients of `clearances` (`clearance_gradients`'s second part)."""
        return lambda Q: self.clearance_gradients(Q)[1]

    def joint_frames(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """((K, J + 1, 3, 3), (K, J + 1, 3)) world rotations and positions of every joint
        of the model, by Pinocchio index (0: the universe, the identity), at each
        configuration of ``Q`` (K, n) [rad]: Pinocchio's ``data.oMi`` (round-off)."""
        Q = self._configurations(Q)
        J = len(self._table[0])
        R = np.empty((len(Q), J + 1, 3, 3))
        p = np.empty((len(Q), J + 1, 3))
        R[:, 0], p[:, 0] = np.eye(3), 0.0
        Rj = np.empty((len(Q), J, 3, 3))
        pj = np.empty((len(Q), J, 3))
        self._lib.geosyn_spheres_frames(self._handle, _address(Q), len(Q), _address(Rj),
                                        _address(pj))  # fmt: skip
        R[:, 1:], p[:, 1:] = Rj, pj
        return R, p

    def obstacle_distances(self, Q: np.ndarray) -> np.ndarray:
        """(K, S, O) the clearance [m] of every sphere to every obstacle at each
        configuration of ``Q`` (K, n) [rad]."""
        Q = self._configurations(Q)
        out = np.empty((len(Q), len(self._radius), len(self.obstacles)))
        if out.size:
            self._lib.geosyn_spheres_obstacle_distances(self._handle, _address(Q), len(Q),
                                                        _address(out))  # fmt: skip
        return out

    def group_distances(self, Q: np.ndarray, group: np.ndarray, count: int) -> np.ndarray:
        """(K, count, O) per group of spheres the smallest clearance [m] of its spheres to
        every obstacle (`obstacle_distances` reduced by ``group`` (S,), each sphere's
        group in ``[0, count)`` or -1 for none; +inf for an empty group) at each
        configuration of ``Q`` (K, n) [rad]."""
        Q = self._configurations(Q)
        group = np.ascontiguousarray(group, dtype=np.int32)
        if group.shape != self._radius.shape or (group.size and group.max() >= count):
            raise InvalidArgument(f"group: one index in [-1, {count}) per sphere "
                                  f"({len(self._radius)}), got {group.shape} with max "
                                  f"{group.max(initial=-1)}")  # fmt: skip
        out = np.empty((len(Q), count, len(self.obstacles)))
        if out.size:
            self._lib.geosyn_spheres_group_distances(self._handle, _address(Q), len(Q),
                                                     _address(group), count, _address(out))  # fmt: skip
        return out

    def self_clearances(self, Q: np.ndarray, frames: Frames | None = None) -> np.ndarray:
        """As `SphereCheck.self_clearances` (``frames`` is not needed)."""
        Q = self._configurations(Q)
        if not self._n_pairs:
            return np.full((len(Q), 0), math.inf)
        out = np.empty((len(Q), self._n_pairs))
        self._lib.geosyn_spheres_self_clearances(self._handle, _address(Q), len(Q), _address(out))
        return out

    def self_valid(self, Q: np.ndarray, frames: Frames | None = None) -> np.ndarray:
        """As `SphereCheck.self_valid`."""
        Q = self._configurations(Q)
        if not self._n_pairs:
            return np.ones(len(Q), dtype=bool)
        return np.asarray(np.all(self.self_clearances(Q) >= self.self_floors(Q), axis=1))

    def valid(self, Q: np.ndarray, margin: float) -> np.ndarray:
        """As `SphereCheck.valid`, in one C call."""
        Q = self._configurations(Q)
        out = np.empty(len(Q), dtype=np.uint8)
        self._lib.geosyn_spheres_valid(self._handle, _address(Q), len(Q), float(margin),
                                       int(bool(self._n_pairs)), 0, _address(out))  # fmt: skip
        return out.view(np.bool_)

    def all_valid(self, Q: np.ndarray, margin: float) -> bool:
        """Whether every configuration of ``Q`` (K, n) [rad] is valid (`valid`), stopping
        at the first invalid one."""
        Q = self._configurations(Q)
        if len(self._valid_out) < len(Q):
            self._valid_out = np.empty(max(len(Q), 64), dtype=np.uint8)
        count = self._lib.geosyn_spheres_valid(self._handle, _address(Q), len(Q), float(margin),
                                               int(bool(self._n_pairs)), 1,
                                               _address(self._valid_out))  # fmt: skip
        return bool(count == len(Q))

    def segment_valid(self, a: np.ndarray, b: np.ndarray, resolution: float,
                      margin: float) -> bool:  # fmt: skip
        """Whether the segment ``a`` -> ``b`` (n,) [rad] is valid (`valid`) at the points
        ``a + (i / k) (b - a)``, i = 1 .. k, ``k = max(1, ceil(|b - a| / resolution))``
        (``a`` itself not checked), stopping at the first invalid one."""
        a = np.ascontiguousarray(a, dtype=float)
        b = np.ascontiguousarray(b, dtype=float)
        return _verdict(self._lib.geosyn_spheres_segment_valid(
            self._handle, _address(a), _address(b), float(resolution), float(margin),
            int(bool(self._n_pairs))))  # fmt: skip

    def path_valid(self, X: np.ndarray, resolution: float, margin: float) -> bool:
        """Whether every segment of the path ``X`` (T, n) [rad] is valid (`segment_valid`;
        ``X[0]`` itself not checked), in one C call, stopping at the first invalid one."""
        X = self._configurations(X)
        return _verdict(self._lib.geosyn_spheres_path_valid(
            self._handle, _address(X), len(X), float(resolution), float(margin),
            int(bool(self._n_pairs))))  # fmt: skip

    def rrt_connect(self, q0: np.ndarray, q1: np.ndarray, lo: np.ndarray, hi: np.ndarray, *,
                    margin: float, step: float = RRT_STEP, resolution: float = 0.05,
                    budget: float = 2.0, seed: int = 0, max_nodes: int = 20000,
                    domain: tuple[float, float, float] | None = DYNAMIC_DOMAIN,
                    balance: bool = True, near: Near | None = None,
                    ) -> tuple[np.ndarray | None, int]:  # fmt: skip
        """RRT-Connect in C: `geosyn.metrics.planning.rrt.rrt_connect`'s search (the
        same arguments and result; balanced trees, the dynamic domain, the ``near`` box)
        on `valid` at ``margin`` [m], with its own seeded sampler (xorshift128+), in
        calls of at most `RRT_SLICE` s."""
        domain = check_domain(domain)
        n = self.robot.model.nq
        q0, q1 = (np.ascontiguousarray(x, dtype=float) for x in (q0, q1))
        lo, hi = (np.ascontiguousarray(x, dtype=float) for x in (lo, hi))
        n_lo, n_hi, share = check_near(near, lo, hi)
        n_lo, n_hi = np.ascontiguousarray(n_lo), np.ascontiguousarray(n_hi)
        if self.segment_valid(q0, q1, resolution, margin):
            return np.array([q0, q1]), 2
        trees = [np.empty((max_nodes, n)) for _ in range(2)]
        parents = [np.full(max_nodes, -1, dtype=np.intc) for _ in range(2)]
        radii = [np.full(max_nodes, np.inf) for _ in range(2)]
        trees[0][0], trees[1][0] = q0, q1
        dd = np.array(domain if domain is not None else (0.0, 0.0, 0.0), dtype=float)
        size, turn, ends = (np.array(x, dtype=np.intc) for x in ([1, 1], [0], [0, 0]))
        state = np.random.default_rng(seed).integers(1, 2**63, size=2, dtype=np.uint64)
        end = time.perf_counter() + budget
        status = 0
        while status == 0 and (left := end - time.perf_counter()) > 0:
            status = self._lib.geosyn_spheres_rrt_connect(
                self._handle, _address(lo), _address(hi), _address(n_lo), _address(n_hi),
                share, float(step), float(resolution),
                float(margin), int(bool(self._n_pairs)), _address(trees[0]),
                _address(parents[0]), _address(radii[0]), _address(trees[1]),
                _address(parents[1]), _address(radii[1]), _address(size), int(max_nodes),
                _address(turn), _address(state), min(left, RRT_SLICE), _address(dd),
                int(bool(balance)), _address(ends))  # fmt: skip
        grown = int(size.sum())
        if status != 1:
            return None, grown
        branches = []
        for t in range(2):
            i, out = int(ends[t]), []
            while i >= 0:
                out.append(trees[t][i])
                i = int(parents[t][i])
            branches.append(np.array(out))
        return np.vstack([branches[0][::-1], branches[1][1:]]), grown


class _Finalizer:
    """Frees the C handle when the check is garbage-collected."""

    def __init__(self, lib: ctypes.CDLL, handle: int) -> None:
        self._lib, self._handle = lib, handle

    def __del__(self) -> None:
        self._lib.geosyn_spheres_free(self._handle)


def sphere_check(robot: Robot, spheres: Sequence[CollisionSphere]) -> tuple[SphereCheck, str]:
    """(the check, a note): `NativeSphereCheck` when the robot's joints and a C compiler
    allow it (note ""), else the numpy `SphereCheck` and why (also warned, once per
    reason)."""
    try:
        return NativeSphereCheck(robot, spheres), ""
    except (ValueError, CodegenError) as err:
        note = f"sampling checks in numpy (about 50x slower): {err}"
        _warn_once(note)
        return SphereCheck(robot, spheres), note


@functools.cache
def _warn_once(note: str) -> None:
    warnings.warn(f"Planner: {note}", UserWarning, stacklevel=4)
