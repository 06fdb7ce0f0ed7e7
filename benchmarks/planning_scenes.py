"""The Panda scenes of `benchmarks/planning.py` (issue 11), defined once, as data.

Read by both sides of the benchmark: by ``planning.py`` in the main venv (geosyn) and by
``geodex_runner.py`` in the geodex venv (Python >= 3.12, numpy and pygeodex only), so this
file imports nothing but the standard library and numpy, and each side converts the
obstacles to its own types.

Conventions:

- World frame = the Panda's base frame (``panda_link0``), z up; lengths in metres,
  angles in radians.
- `Box`: ``center``, **half** side lengths ``half_extents`` (geodex's ``Scene.add_box``
  takes full sizes: 2 x these) and a URDF-convention ``rpy`` orientation
  (``R = Rz(yaw) Ry(pitch) Rx(roll)``, columns = box axes in the world).
- `Cylinder`: ``center``, ``radius``, ``half_length`` along its local z axis, ``rpy``.
- `Capsule`: segment ``p0``-``p1`` and ``radius``.
- `Sphere`: ``center``, ``radius``.
- `HalfSpace`: the obstacle is ``{x : normal . x <= offset}``; free space is above.
- Configurations ``q_start``, ``q_goal``: (7,) positions of ``panda_joint1`` ...
  ``panda_joint7`` [rad], the order of both geosyn's ``load_robot("panda")`` and geodex's
  ``robots.Panda()``; both use the same limits.

Every start and goal is collision-free for geodex's checker (VAMP, 59 spheres), and
``blocked`` records whether the straight joint-space line between them collides there
(``benchmarks/planning.py --check-scenes`` re-checks both and names the obstacles hit).
The configurations were found by a posture-regularised IK on the hand TCP
(``panda_hand_tcp``) and rounded to 1 mrad; the comment next to each gives the TCP
position it reaches.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

Vec3 = tuple[float, float, float]

PANDA_HOME = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)
"""(7,) the geodex quickstart's posture of joints 2-7 (with joint 1 = 0) [rad]."""


@dataclass(frozen=True)
class Box:
    """An oriented box: ``center`` (3,) [m], ``half_extents`` (3,) half sizes [m], ``rpy``."""

    center: Vec3
    half_extents: Vec3
    rpy: Vec3 = (0.0, 0.0, 0.0)
    name: str = "box"


@dataclass(frozen=True)
class Sphere:
    """A ball: ``center`` (3,) [m], ``radius`` [m]."""

    center: Vec3
    radius: float
    name: str = "sphere"


@dataclass(frozen=True)
class Cylinder:
    """A solid cylinder: ``center`` (3,) [m], ``radius`` [m], ``half_length`` along local z [m]."""

    center: Vec3
    radius: float
    half_length: float
    rpy: Vec3 = (0.0, 0.0, 0.0)
    name: str = "cylinder"


@dataclass(frozen=True)
class Capsule:
    """Points within ``radius`` [m] of the segment ``p0``-``p1`` (3,) [m]."""

    p0: Vec3
    p1: Vec3
    radius: float
    name: str = "capsule"


@dataclass(frozen=True)
class HalfSpace:
    """The obstacle ``{x : normal . x <= offset}``: unit ``normal`` (3,), ``offset`` [m]."""

    normal: Vec3
    offset: float
    name: str = "half-space"


Obstacle = Box | Sphere | Cylinder | Capsule | HalfSpace


@dataclass(frozen=True)
class Scene:
    """One planning query.

    Attributes:
        name: short identifier (used on the command line and in result files).
        description: one line for tables and RESULTS.md.
        obstacles: the obstacles.
        q_start: (7,) start configuration [rad].
        q_goal: (7,) goal configuration [rad].
        blocked: True when the straight joint-space line from start to goal collides
            (geodex's checker); False for scenes that are free on purpose.
    """

    name: str
    description: str
    obstacles: tuple[Obstacle, ...]
    q_start: tuple[float, ...]
    q_goal: tuple[float, ...]
    blocked: bool = True
    notes: str = field(default="")


# -- geometry helpers shared by both sides ---------------------------------------------


def rpy_matrix(rpy: Vec3) -> np.ndarray:
    """(3, 3) rotation ``Rz(yaw) Ry(pitch) Rx(roll)`` of URDF ``rpy`` (roll, pitch, yaw) [rad]."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(y),
        math.sin(y),
    )
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def matrix_quaternion_xyzw(R: np.ndarray) -> tuple[float, float, float, float]:
    """Unit quaternion (qx, qy, qz, qw) of a (3, 3) rotation matrix (geodex's order)."""
    R = np.asarray(R, dtype=float)
    t = float(np.trace(R))
    if t > 0.0:
        s = 2.0 * math.sqrt(t + 1.0)
        q = ((R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s, s / 4)
    else:
        i = int(np.argmax(np.diag(R)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(1.0 + R[i, i] - R[j, j] - R[k, k])
        v = [0.0, 0.0, 0.0]
        v[i] = s / 4
        v[j] = (R[j, i] + R[i, j]) / s
        v[k] = (R[k, i] + R[i, k]) / s
        q = (v[0], v[1], v[2], (R[k, j] - R[j, k]) / s)
    n = math.sqrt(sum(c * c for c in q))
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


def frame_with_z_axis(axis: np.ndarray) -> np.ndarray:
    """A (3, 3) rotation whose third column is the unit vector along ``axis`` (3,)."""
    z = np.asarray(axis, dtype=float)
    z = z / np.linalg.norm(z)
    helper = np.eye(3)[int(np.argmin(np.abs(z)))]
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def resample(path: np.ndarray, max_step: float) -> np.ndarray:
    """Piecewise-linear resampling of a joint path (T, n) so no step exceeds ``max_step`` [rad].

    Every original waypoint is kept; each segment is split evenly (2-norm of the step).
    """
    path = np.asarray(path, dtype=float)
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:], strict=True):
        k = max(1, int(math.ceil(float(np.linalg.norm(b - a)) / max_step)))
        s = np.arange(1, k + 1)[:, None] / k
        out.append(a + s * (b - a))
    return np.concatenate(out, axis=0)


def straight_line(scene: Scene, max_step: float) -> np.ndarray:
    """(T, 7) the straight joint-space line from start to goal, steps <= ``max_step`` [rad]."""
    return resample(np.array([scene.q_start, scene.q_goal]), max_step)


# -- the suite ------------------------------------------------------------------------


def _shelf() -> tuple[Obstacle, ...]:
    # Open towards the robot (-x); inner width 0.70 m (y), depth 0.40 m (x from 0.45 m).
    x0, depth, half_w, t = 0.45, 0.40, 0.36, 0.01
    xc = x0 + depth / 2
    boards = [
        Box((xc, 0.0, 0.27), (depth / 2, half_w, t), name="bottom board"),
        Box((xc, 0.0, 0.55), (depth / 2, half_w, t), name="middle board"),
        Box((xc, 0.0, 0.85), (depth / 2, half_w, t), name="top board"),
        Box((x0 + depth + t, 0.0, 0.56), (t, half_w, 0.30), name="back wall"),
        Box((xc, half_w + t, 0.56), (depth / 2, t, 0.30), name="left side"),
        Box((xc, -half_w - t, 0.56), (depth / 2, t, 0.30), name="right side"),
    ]
    return tuple(boards)


def _shelf_compartments() -> tuple[Obstacle, ...]:
    # Open towards the robot (-x), 0.35 m deep from x = 0.40 m, two floors and a divider:
    # four compartments 0.28 m wide and 0.27 m high.
    x0, depth, hw, t = 0.40, 0.35, 0.30, 0.01
    xc = x0 + depth / 2
    return (
        Box((xc, 0.0, 0.20), (depth / 2, hw, t), name="bottom board"),
        Box((xc, 0.0, 0.48), (depth / 2, hw, t), name="middle board"),
        Box((xc, 0.0, 0.76), (depth / 2, hw, t), name="top board"),
        Box((x0 + depth + t, 0.0, 0.48), (t, hw, 0.29), name="back wall"),
        Box((xc, 0.0, 0.48), (depth / 2, t, 0.28), name="divider"),
        Box((xc, hw + t, 0.48), (depth / 2, t, 0.29), name="left side"),
        Box((xc, -hw - t, 0.48), (depth / 2, t, 0.29), name="right side"),
    )


def _window() -> tuple[Obstacle, ...]:
    # a 2 cm wall at x = 0.5 m with a 0.30 m x 0.36 m window (y in [-0.15, 0.15],
    # z in [0.44, 0.70])
    return (
        Box((0.50, -0.40, 0.50), (0.01, 0.25, 0.50), name="wall left"),
        Box((0.50, 0.40, 0.50), (0.01, 0.25, 0.50), name="wall right"),
        Box((0.50, 0.0, 0.22), (0.01, 0.15, 0.22), name="sill"),
        Box((0.50, 0.0, 0.85), (0.01, 0.15, 0.15), name="lintel"),
    )


def _cluttered_table() -> tuple[Obstacle, ...]:
    return (
        Box((0.55, 0.0, 0.15), (0.25, 0.45, 0.02), name="table top"),
        Cylinder((0.50, -0.12, 0.25), 0.035, 0.08, name="bottle"),
        Box((0.62, 0.05, 0.22), (0.04, 0.06, 0.05), name="box"),
        Sphere((0.45, 0.12, 0.21), 0.04, name="ball"),
        Cylinder((0.68, -0.22, 0.27), 0.03, 0.10, name="tall bottle"),
    )


SCENES: tuple[Scene, ...] = (
    Scene(
        name="quickstart",
        description="geodex quickstart: 0.1 x 0.1 x 0.8 m box post, joint 1 from -1.1 to 1.1",
        obstacles=(Box((0.4, 0.0, 0.3), (0.05, 0.05, 0.4), name="post"),),
        q_start=(-1.1,) + PANDA_HOME[1:],
        q_goal=(1.1,) + PANDA_HOME[1:],
    ),
    Scene(
        name="shelf",
        description="shelf with two compartments: hand from the lower to the upper one",
        obstacles=_shelf(),
        # TCP (0.58, 0, 0.38), approach +x pitched 0.5 rad down -> TCP (0.60, 0, 0.70), approach +x
        q_start=(0.0, -0.096, 0.0, -2.575, 0.0, 3.549, 0.785),
        q_goal=(0.0, -0.256, 0.0, -2.16, 0.0, 3.475, 0.785),
    ),
    Scene(
        name="table_box",
        description="table with a box on it: hand low over the table, round the box",
        obstacles=(
            Box((0.5, 0.0, 0.2), (0.25, 0.4, 0.02), name="table top"),
            Box((0.5, 0.0, 0.35), (0.08, 0.08, 0.13), name="box on table"),
        ),
        # TCP (0.50, -0.25, 0.32) -> (0.50, 0.25, 0.32), hand pointing down
        q_start=(-0.247, 0.042, -0.219, -2.038, 0.011, 2.079, 0.314),
        q_goal=(0.247, 0.042, 0.219, -2.038, -0.011, 2.079, 1.257),
    ),
    Scene(
        name="narrow_gap",
        description="0.2 m gap between two 0.3 m tall boxes: reach down into it from the side",
        obstacles=(
            Box((0.5, -0.2, 0.15), (0.12, 0.1, 0.15), name="right box"),
            Box((0.5, 0.2, 0.15), (0.12, 0.1, 0.15), name="left box"),
        ),
        # TCP (0.45, -0.48, 0.20) down -> (0.50, 0, 0.18) down, fingers along x
        q_start=(-0.673, 0.469, -0.163, -1.761, 0.092, 2.223, -0.09),
        q_goal=(-0.075, 0.086, 0.075, -2.387, -0.01, 2.473, -0.778),
    ),
    Scene(
        name="sphere_cluster",
        description="cluster of six spheres (r 0.05-0.08 m) between two low hand poses",
        obstacles=(
            Sphere((0.55, 0.0, 0.35), 0.08, name="s0"),
            Sphere((0.45, 0.12, 0.55), 0.07, name="s1"),
            Sphere((0.62, -0.14, 0.52), 0.06, name="s2"),
            Sphere((0.40, -0.06, 0.22), 0.06, name="s3"),
            Sphere((0.35, 0.16, 0.30), 0.05, name="s4"),
            Sphere((0.68, 0.15, 0.30), 0.06, name="s5"),
        ),
        # TCP (0.45, -0.35, 0.35) -> (0.45, 0.35, 0.35), hand pointing down
        q_start=(-0.359, 0.053, -0.308, -1.947, 0.018, 1.998, 0.112),
        q_goal=(0.359, 0.053, 0.308, -1.947, -0.018, 1.998, 1.459),
    ),
    Scene(
        name="floor",
        description="half-space floor 0.035 m below the base: hand low near the base, then far out",
        obstacles=(HalfSpace((0.0, 0.0, 1.0), -0.035, name="floor"),),
        # TCP (0.20, -0.20, 0.04), hand tilted 1.3 rad outwards from down -> TCP (0.65, 0.20, 0.04) down
        q_start=(-0.661, 0.704, -0.116, -2.132, 0.055, 1.53, -0.06),
        q_goal=(0.284, 0.8, 0.016, -1.652, -0.018, 2.452, 1.095),
        notes="geodex's base sphere (z 0.05, r 0.08) reaches z = -0.03: a floor at z = 0 "
        "puts every configuration in collision there, hence -0.035",
    ),
    Scene(
        name="free",
        description="no obstacles: the quickstart start to a folded pose on the other side",
        obstacles=(),
        q_start=(-1.1,) + PANDA_HOME[1:],
        q_goal=(1.0, 0.3, 0.5, -1.5, 0.3, 2.0, 0.0),
        blocked=False,
    ),
    Scene(
        name="pillar_pipe_panel",
        description="own: cylinder pillar, capsule pipe above, tilted panel behind",
        obstacles=(
            Cylinder((0.45, 0.0, 0.25), 0.04, 0.25, name="pillar"),
            Capsule((0.25, -0.5, 0.80), (0.65, 0.5, 0.80), 0.03, name="pipe"),
            Box((0.68, 0.0, 0.40), (0.01, 0.30, 0.25), rpy=(0.0, -0.3, 0.0), name="panel"),
        ),
        # TCP (0.45, -0.35, 0.35) -> (0.45, 0.35, 0.35), hand pointing down
        q_start=(-0.359, 0.053, -0.308, -1.947, 0.018, 1.998, 0.112),
        q_goal=(0.359, 0.053, 0.308, -1.947, -0.018, 1.998, 1.459),
    ),
    # -- issue 22: constrained scenes; both ends >= 15 mm from the URDF collision meshes
    # (coal), the straight joint line through an obstacle (found by a seeded pose IK on
    # the hand TCP, rounded to 1 mrad)
    Scene(
        name="shelf_compartments",
        description="own: shelf of four compartments, lower right to upper left, hand forward",
        obstacles=_shelf_compartments(),
        # TCP (0.55, -0.15, 0.30) -> (0.55, 0.15, 0.60), hand pointing +x
        q_start=(-0.619, -0.028, 0.258, -2.553, 2.708, 2.139, 1.037),
        q_goal=(-1.023, -0.863, 1.12, -2.073, 2.521, 3.026, 2.158),
    ),
    Scene(
        name="window",
        description="own: wall with a window, from in front of the wall through the window",
        obstacles=_window(),
        # TCP (0.35, -0.30, 0.45) -> (0.62, 0.0, 0.55), hand pointing +x
        q_start=(0.55, -1.347, -1.32, -2.337, -2.896, 3.366, -0.694),
        q_goal=(0.88, -0.312, -0.833, -2.054, -2.896, 2.847, 0.321),
    ),
    Scene(
        name="cluttered_table",
        description="own: table with two bottles, a box and a ball, across the clutter",
        obstacles=_cluttered_table(),
        # TCP (0.45, -0.28, 0.25) -> (0.55, 0.25, 0.24), hand pointing down
        q_start=(0.386, 0.071, -0.95, -2.231, 0.075, 2.271, 0.174),
        q_goal=(0.723, 0.271, -0.314, -1.962, 0.104, 2.218, 1.142),
    ),
    Scene(
        name="pillar",
        description="own: floor-to-ceiling pillar (r 0.07 m) in front, from one side to the other",
        obstacles=(Cylinder((0.50, 0.0, 0.5), 0.07, 0.5, name="pillar"),),
        # TCP (0.45, -0.30, 0.35) -> (0.45, 0.30, 0.35), hand pointing down
        q_start=(-0.785, -0.037, 0.195, -2.054, 0.008, 2.017, 0.191),
        q_goal=(-0.229, -0.053, 0.804, -2.054, 0.042, 2.017, 1.342),
    ),
    Scene(
        name="low_bar",
        description="own: horizontal bar at 0.36 m, from above it to reaching under it",
        obstacles=(Capsule((0.56, -0.5, 0.36), (0.56, 0.5, 0.36), 0.02, name="bar"),),
        # TCP (0.55, 0.20, 0.62) hand down -> (0.68, 0.0, 0.20) hand pointing +x
        q_start=(0.018, 0.324, 0.492, -0.889, -0.163, 1.182, 1.211),
        q_goal=(1.174, 1.045, -1.153, -2.16, -2.896, 2.19, 1.579),
    ),
    Scene(
        name="slot",
        description="own: 0.17 m horizontal slot between two blocks, into the slot",
        obstacles=(
            Box((0.65, 0.0, 0.25), (0.15, 0.30, 0.10), name="lower block"),
            Box((0.65, 0.0, 0.62), (0.15, 0.30, 0.10), name="upper block"),
        ),
        # TCP (0.30, -0.40, 0.70) -> (0.60, 0.0, 0.435), hand pointing +x
        q_start=(0.873, -1.762, -0.784, -2.126, -1.129, 2.373, -2.468),
        q_goal=(1.604, -1.762, -1.35, -2.428, -2.868, 2.233, -1.155),
    ),
)
"""The benchmark suite, in table order."""


def scene_by_name(name: str) -> Scene:
    """The scene called ``name``; raises KeyError listing the available names."""
    for s in SCENES:
        if s.name == name:
            return s
    raise KeyError(f"scene {name!r} is unknown; available: {', '.join(s.name for s in SCENES)}")
