"""Motion capture to joint angles on the (scaled) MyoArm.

1. Scale: each segment of `SEGMENTS` gets the factor (median captured length) / (model
   length at the reference posture); `load_myoarm` applies it.
2. Thorax frame: per frame, from the capture's shoulders, ``Spine1`` and ``Neck`` (x from
   the left to the right shoulder, z the spine's upward direction made orthogonal), with
   origin at ``RightShoulder``; the arm's keypoints are expressed in it, so the torso's
   own motion is removed. One constant rotation and offset map this frame to the model's
   chest frame; they are calibrated on a subset of frames, alternating per-frame IK and
   a least-squares rigid fit (Kabsch), from an initial guess that matches "right" and "up".
3. Per-frame IK on the independent coordinates z (q = S z + c), with the box of z that
   keeps every joint (independent and dependent) inside its file range; Levenberg-
   Marquardt-type trust-region least squares (scipy, analytic Jacobian S^T J^T),
   warm-started from the previous frame.
4. Smoothing: zero-phase 2nd-order Butterworth low-pass on z (default 6 Hz), re-clipped
   to the box; residuals are reported before and after it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pinocchio as pin
import scipy.optimize
import scipy.signal
from scipy.spatial.transform import Rotation

from geosyn.robots import Robot
from geosyn.robots.couplings import Coupling
from geosyn.synergies.errors import InvalidSynergyInput
from geosyn.synergies.human.data import MOCAP_JOINTS, MocapSequence
from geosyn.synergies.human.myoarm import KEYPOINT_FRAMES, SEGMENTS

FITTED: tuple[str, ...] = (
    "RightArm",
    "RightForeArm",
    "RightHand",
    "RightHandIndex1",
    "RightHandMiddle1",
    "RightHandPinky1",
)
"""Keypoints fitted by the IK (the sternoclavicular point is the frame's origin)."""


class ArmFit(NamedTuple):
    """Joint angles of one sequence and how well they reproduce the capture."""

    name: str
    t: np.ndarray  # (T,) [s]
    z: np.ndarray  # (T, nz) smoothed independent coordinates [rad]
    z_raw: np.ndarray  # (T, nz) per-frame IK solutions [rad]
    targets: np.ndarray  # (T, K, 3) keypoints in the model's frame [m]
    residual: np.ndarray  # (T, K) keypoint distances after smoothing [m]
    residual_raw: np.ndarray  # (T, K) before smoothing [m]
    at_limit: np.ndarray  # (T,) frames with a coordinate on its bound


class Calibration(NamedTuple):
    """Constant map from the capture's thorax frame to the model's world frame."""

    R: np.ndarray  # (3, 3) rotation
    t: np.ndarray  # (3,) translation [m]
    rms: float  # keypoint RMS on the calibration frames [m]
    rounds: int


def coupling_of(robot: Robot) -> Coupling:
    """The robot's coupling (the MyoArm has one).

    Raises:
        InvalidSynergyInput: the robot has no joint coupling.
    """
    if robot.coupling is None:
        raise InvalidSynergyInput(
            f"robot {robot.name!r} has no joint coupling; expected the MyoArm", "robot"
        )
    return robot.coupling


def _index(name: str) -> int:
    return MOCAP_JOINTS.index(name)


def segment_lengths(positions: np.ndarray) -> dict[str, float]:
    """Median captured length of each segment [m].

    Args:
        positions: (T, 53, 3) joint positions [m] (several sequences stacked).
    """
    return {
        s: float(
            np.median(np.linalg.norm(positions[:, _index(a)] - positions[:, _index(b)], axis=1))
        )
        for s, (a, b) in SEGMENTS.items()
    }


def model_keypoints(robot: Robot, q: np.ndarray, names: Sequence[str] = FITTED) -> np.ndarray:
    """(K, 3) model keypoints (body origins of `KEYPOINT_FRAMES`) at q [m]."""
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    return np.array([data.oMf[robot.frame_id(KEYPOINT_FRAMES[n])].translation for n in names])


def model_segment_lengths(robot: Robot) -> dict[str, float]:
    """Segment lengths of the model at its reference posture (q = c + S z(qpos0)) [m]."""
    q0 = coupling_of(robot).q(np.clip(np.zeros(coupling_of(robot).nz), *z_box(robot)))
    names = tuple(KEYPOINT_FRAMES)
    p = dict(zip(names, model_keypoints(robot, q0, names), strict=True))
    return {s: float(np.linalg.norm(p[a] - p[b])) for s, (a, b) in SEGMENTS.items()}


def z_box(robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of z that keep every joint in its range (rows of S with one entry)."""
    S, c = coupling_of(robot).S, coupling_of(robot).c
    lo, hi = np.full(S.shape[1], -np.inf), np.full(S.shape[1], np.inf)
    for i in range(S.shape[0]):
        nz = np.flatnonzero(S[i])
        if len(nz) != 1:
            continue
        k, s = int(nz[0]), float(S[i, nz[0]])
        a, b = (robot.q_min[i] - c[i]) / s, (robot.q_max[i] - c[i]) / s
        lo[k], hi[k] = max(lo[k], min(a, b)), min(hi[k], max(a, b))
    return lo, hi


def thorax_frames(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame thorax rotation (T, 3, 3) (columns: right, forward, up) and origin (T, 3)."""
    right = positions[:, _index("RightShoulder")] - positions[:, _index("LeftShoulder")]
    up = positions[:, _index("Neck")] - positions[:, _index("Spine1")]
    x = right / np.linalg.norm(right, axis=1, keepdims=True)
    up = up - np.sum(up * x, axis=1, keepdims=True) * x
    z = up / np.linalg.norm(up, axis=1, keepdims=True)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=2), positions[:, _index("RightShoulder")]


def local_keypoints(positions: np.ndarray) -> np.ndarray:
    """(T, K, 3) fitted keypoints in the capture's thorax frame [m]."""
    R, o = thorax_frames(positions)
    P = positions[:, [_index(n) for n in FITTED]] - o[:, None, :]
    return np.einsum("tji,tkj->tki", R, P)


class _Solver:
    """Per-frame IK on z (analytic Jacobian); allocates one Pinocchio data."""

    def __init__(self, robot: Robot) -> None:
        self.robot, self.model = robot, robot.model
        self.data = robot.model.createData()
        self.S, self.c = coupling_of(robot).S, coupling_of(robot).c
        self.frames = [robot.frame_id(KEYPOINT_FRAMES[n]) for n in FITTED]
        lo, hi = z_box(robot)
        self.lo, self.hi = lo + 1e-9, hi - 1e-9

    def residual(self, z: np.ndarray, target: np.ndarray) -> np.ndarray:
        pin.framesForwardKinematics(self.model, self.data, self.S @ z + self.c)
        return np.concatenate(
            [self.data.oMf[f].translation - p for f, p in zip(self.frames, target, strict=True)]
        )

    def jacobian(self, z: np.ndarray, target: np.ndarray) -> np.ndarray:
        q = self.S @ z + self.c
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        rf = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        J = [pin.getFrameJacobian(self.model, self.data, f, rf)[:3] for f in self.frames]
        return np.vstack(J) @ self.S

    def solve(self, target: np.ndarray, z0: np.ndarray) -> np.ndarray:
        z0 = np.clip(z0, self.lo, self.hi)
        sol = scipy.optimize.least_squares(
            self.residual, z0, jac=self.jacobian, bounds=(self.lo, self.hi), args=(target,),
            method="trf", xtol=1e-10, ftol=1e-12, max_nfev=100,
        )  # fmt: skip
        return np.asarray(sol.x)


def solve_frame(robot: Robot, target: np.ndarray, z0: np.ndarray) -> np.ndarray:
    """IK of one frame: z in the joint-limit box minimizing the keypoint distances.

    Args:
        robot: the arm (with ``robot.coupling``).
        target: (K, 3) keypoints of `FITTED` in the model's world frame [m].
        z0: (nz,) initial guess [rad] (clipped into the box).

    Returns:
        (nz,) independent coordinates [rad].
    """
    return _Solver(robot).solve(np.asarray(target, dtype=np.float64), np.asarray(z0, dtype=float))


def _solve_all(solver: _Solver, targets: np.ndarray, z0: np.ndarray) -> np.ndarray:
    z, out = z0, np.empty((len(targets), len(z0)))
    for i, target in enumerate(targets):
        z = solver.solve(target, z)
        out[i] = z
    return out


def calibrate(
    robot: Robot, local: np.ndarray, *, frames: int = 120, rounds: int = 8
) -> Calibration:
    """The constant map from the capture's thorax frame to the model (see the module doc).

    Args:
        robot: the (scaled) arm.
        local: (T, K, 3) keypoints in the capture's thorax frame [m].
        frames: number of evenly spaced calibration frames.
        rounds: alternations of IK and rigid fit.
    """
    solver = _Solver(robot)
    sub = local[np.linspace(0, len(local) - 1, frames).astype(int)]
    q0 = coupling_of(robot).q(np.clip(np.zeros(coupling_of(robot).nz), solver.lo, solver.hi))
    kp = model_keypoints(robot, q0, ("RightShoulder", "RightArm"))
    right = kp[1] - kp[0]
    up = np.array([0.0, 0.0, 1.0])
    x = right - (right @ up) * up
    x /= np.linalg.norm(x)
    R, t = np.column_stack([x, np.cross(up, x), up]), kp[0]
    z = np.clip(np.zeros(coupling_of(robot).nz), solver.lo, solver.hi)
    rms = np.inf
    for _ in range(rounds):
        Z = _solve_all(solver, sub @ R.T + t, z)
        model = np.array([model_keypoints(robot, coupling_of(robot).q(zz)) for zz in Z])
        A, B = sub.reshape(-1, 3), model.reshape(-1, 3)
        ca, cb = A.mean(axis=0), B.mean(axis=0)
        U, _, Vt = np.linalg.svd((A - ca).T @ (B - cb))
        D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
        R = (U @ D @ Vt).T
        t = cb - R @ ca
        rms = float(np.sqrt(np.mean(np.sum((A @ R.T + t - B) ** 2, axis=1))))
        z = Z[0]
    return Calibration(R, t, rms, rounds)


def fit_sequence(
    robot: Robot, seq: MocapSequence, calib: Calibration, *, cutoff: float = 6.0
) -> ArmFit:
    """Per-frame IK of one sequence, then zero-phase smoothing (see the module doc).

    Args:
        robot: the (scaled) arm.
        seq: the capture.
        calib: from `calibrate`.
        cutoff: low-pass cut-off [Hz] (below the Nyquist frequency ``fps / 2``).

    Raises:
        InvalidSynergyInput: ``cutoff`` not in (0, fps/2).
    """
    if not 0.0 < cutoff < seq.fps / 2:
        raise InvalidSynergyInput(
            f"cutoff must be in (0, {seq.fps / 2:g}) Hz for {seq.fps:g} fps, got {cutoff!r}",
            "cutoff",
        )
    solver = _Solver(robot)
    targets = local_keypoints(seq.positions) @ calib.R.T + calib.t
    z0 = np.clip(np.zeros(coupling_of(robot).nz), solver.lo, solver.hi)
    z0 = _solve_all(solver, targets[:1], z0)[0]
    z_raw = _solve_all(solver, targets, z0)
    b, a = scipy.signal.butter(2, cutoff / (seq.fps / 2))
    z = np.clip(scipy.signal.filtfilt(b, a, z_raw, axis=0), solver.lo, solver.hi)

    def dist(Z: np.ndarray) -> np.ndarray:
        P = np.array([model_keypoints(robot, coupling_of(robot).q(zz)) for zz in Z])
        return np.asarray(np.linalg.norm(P - targets, axis=2))

    at_limit = np.any((z_raw <= solver.lo + 1e-6) | (z_raw >= solver.hi - 1e-6), axis=1)
    t = np.arange(len(z)) / seq.fps
    return ArmFit(seq.name, t, z, z_raw, targets, dist(z), dist(z_raw), at_limit)


def scale_factors(sequences: Sequence[MocapSequence], robot: Robot) -> dict[str, float]:
    """Per-segment factors (captured median length / model length) of `SEGMENTS`."""
    captured = segment_lengths(np.concatenate([s.positions for s in sequences]))
    model = model_segment_lengths(robot)
    return {s: captured[s] / model[s] for s in SEGMENTS}


def rotation_angle(R: np.ndarray) -> float:
    """Angle of a rotation matrix [rad] (for reports)."""
    return float(np.linalg.norm(Rotation.from_matrix(R).as_rotvec()))
