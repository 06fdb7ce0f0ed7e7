"""Motion capture to joint angles on the (scaled) MyoArm.

1. Scale: each segment of `SEGMENTS` gets the factor (median captured length) / (model
   length at the reference posture); `load_myoarm` applies it.
2. Thorax frame: per frame, from the capture's shoulders, ``Spine1`` and ``Neck`` (x from
   the left to the right shoulder, z the spine's upward direction made orthogonal), with
   origin at ``RightShoulder``; the arm's keypoints are expressed in it, so the torso's
   own motion is removed. One constant rotation and offset map this frame to the model's
   chest frame; they are calibrated on a subset of frames, alternating per-frame IK,
   marker placement and a least-squares rigid fit (Kabsch), from an initial guess that
   matches "right" and "up". Marker placement (as OpenSim's scale tool does): each
   keypoint is a point fixed on its body, the body origin moved by a constant offset in
   the body's frame (at most `MARKER_BOUND`), since the capture skeleton's joint centres
   are not the MyoArm's body origins; the offsets are part of `Calibration`.
   Optionally (`RootOffset`) the arm's root also translates freely per frame, for the
   shoulder girdle motion the MyoArm's coupled girdle cannot make; off by default.
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
    root_offset: np.ndarray  # (T, 3) smoothed offset d of the arm's root [m] (zeros if fixed)
    markers: np.ndarray  # (K, 3) keypoint offsets on their bodies used [m] (`Calibration`)


class RootOffset(NamedTuple):
    """A free translation d of the arm's root (the clavicle's base) relative to the thorax,
    solved per frame with the joint angles.

    The MyoArm's shoulder girdle is driven by ``shoulder_elv_r`` alone (the file's
    equalities): it cannot protract, retract or shrug on its own, which the captured
    shoulder does while climbing. ``d`` stands for that missing motion: each fitted
    keypoint is ``p(z) + d``, ``|d_i| <= bound`` and ``weight * d`` is added to the
    least-squares residual (so d is used only where it lowers the keypoint error by more
    than ``weight * |d|``). It is reported (`ArmFit.root_offset`); the joint angles z are
    what the rest of the study uses.
    """

    bound: float = 0.05  # [m] per axis
    weight: float = 0.5  # [1] (residual metres per metre of offset)


class Calibration(NamedTuple):
    """Constant map from the capture's thorax frame to the model's world frame."""

    R: np.ndarray  # (3, 3) rotation
    t: np.ndarray  # (3,) translation [m]
    rms: float  # keypoint RMS on the calibration frames [m]
    rounds: int
    markers: np.ndarray  # (K, 3) keypoint offsets in their bodies' frames [m] (`FITTED`)
    root: RootOffset | None  # the free root offset used (None: root fixed)


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


def model_keypoints(
    robot: Robot,
    q: np.ndarray,
    names: Sequence[str] = FITTED,
    markers: np.ndarray | None = None,
) -> np.ndarray:
    """(K, 3) model keypoints at q [m]: the body origins of `KEYPOINT_FRAMES`, moved by
    ``markers`` (K, 3) [m] given in each body's frame (`Calibration.markers`)."""
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    frames = [data.oMf[robot.frame_id(KEYPOINT_FRAMES[n])] for n in names]
    if markers is None:
        return np.array([f.translation for f in frames])
    return np.array([f.act(m) for f, m in zip(frames, markers, strict=True)])


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


MARKER_BOUND = 0.02
"""Largest keypoint marker offset [m] `calibrate` places by default (see there)."""


class _Solver:
    """Per-frame IK on z, optionally with the arm's root offset d (analytic Jacobian);
    allocates one Pinocchio data."""

    def __init__(
        self, robot: Robot, root: RootOffset | None = None, markers: np.ndarray | None = None
    ) -> None:
        self.robot, self.model = robot, robot.model
        self.markers = np.zeros((len(FITTED), 3)) if markers is None else np.asarray(markers)
        self.data = robot.model.createData()
        self.S, self.c = coupling_of(robot).S, coupling_of(robot).c
        self.frames = [robot.frame_id(KEYPOINT_FRAMES[n]) for n in FITTED]
        lo, hi = z_box(robot)
        self.lo, self.hi = lo + 1e-9, hi - 1e-9
        self.nz = len(lo)
        self.root = root
        if root is not None:
            self.lo = np.concatenate([self.lo, np.full(3, -root.bound)])
            self.hi = np.concatenate([self.hi, np.full(3, root.bound)])

    def residual(self, x: np.ndarray, target: np.ndarray) -> np.ndarray:
        z, d = x[: self.nz], x[self.nz :] if self.root is not None else np.zeros(3)
        pin.framesForwardKinematics(self.model, self.data, self.S @ z + self.c)
        r = [
            self.data.oMf[f].act(m) + d - p
            for f, m, p in zip(self.frames, self.markers, target, strict=True)
        ]
        if self.root is not None:
            r.append(self.root.weight * d)
        return np.concatenate(r)

    def jacobian(self, x: np.ndarray, target: np.ndarray) -> np.ndarray:
        q = self.S @ x[: self.nz] + self.c
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        rf = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        rows = []
        for f, m in zip(self.frames, self.markers, strict=True):
            J6 = pin.getFrameJacobian(self.model, self.data, f, rf)
            r = self.data.oMf[f].rotation @ m  # the point moves by v + w x r
            rows.append(J6[:3] - pin.skew(r) @ J6[3:])
        J = np.vstack(rows) @ self.S
        if self.root is None:
            return J
        K = len(self.frames)
        top = np.hstack([J, np.tile(np.eye(3), (K, 1))])
        bottom = np.hstack([np.zeros((3, self.nz)), self.root.weight * np.eye(3)])
        return np.vstack([top, bottom])

    def solve(self, target: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """(nz,) or (nz + 3,) solution (z, then d when the root is free)."""
        from scipy.optimize import least_squares  # heavy (~0.2 s): imported where used

        x0 = np.clip(x0, self.lo, self.hi)
        sol = least_squares(
            self.residual, x0, jac=self.jacobian, bounds=(self.lo, self.hi), args=(target,),
            method="trf", xtol=1e-10, ftol=1e-12, max_nfev=100,
        )  # fmt: skip
        return np.asarray(sol.x)

    def start(self) -> np.ndarray:
        """The reference posture (z = 0 clipped into the box), offset 0."""
        return np.clip(np.zeros(len(self.lo)), self.lo, self.hi)


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


def _solve_all(solver: _Solver, targets: np.ndarray, x0: np.ndarray) -> np.ndarray:
    x, out = x0, np.empty((len(targets), len(x0)))
    for i, target in enumerate(targets):
        x = solver.solve(target, x)
        out[i] = x
    return out


def _place_markers(solver: _Solver, X: np.ndarray, target: np.ndarray, bound: float) -> np.ndarray:
    """(K, 3) marker offsets: the mean keypoint error in each body's frame at the IK
    solutions X (N, nz [+ 3]) of targets (N, K, 3), each clipped to norm ``bound`` [m]."""
    err = np.zeros((len(X), len(FITTED), 3))
    for i, x in enumerate(X):
        q = solver.S @ x[: solver.nz] + solver.c
        pin.framesForwardKinematics(solver.model, solver.data, q)
        d = x[solver.nz :] if solver.root is not None else np.zeros(3)
        for k, f in enumerate(solver.frames):
            pose = solver.data.oMf[f]
            err[i, k] = pose.rotation.T @ (target[i, k] - d - pose.translation)
    markers = err.mean(axis=0)
    norm = np.linalg.norm(markers, axis=1, keepdims=True)
    return np.asarray(markers * np.minimum(1.0, bound / np.maximum(norm, 1e-12)))


def calibrate(
    robot: Robot,
    local: np.ndarray,
    *,
    frames: int = 120,
    rounds: int = 8,
    root: RootOffset | None = None,
    marker_bound: float = MARKER_BOUND,
) -> Calibration:
    """The constant map from the capture's thorax frame to the model, and the keypoints'
    places on the model's bodies (see the module doc).

    Each round solves the IK of the calibration frames, then sets each keypoint's marker
    offset (in its body's frame) to the mean remaining error there, its norm clipped to
    ``marker_bound`` (the capture's joint centres are not exactly the model's body
    origins: OpenSim's marker placement step), then refits the rigid map (Kabsch).

    Args:
        robot: the (scaled) arm.
        local: (T, K, 3) keypoints in the capture's thorax frame [m].
        frames: number of evenly spaced calibration frames.
        rounds: alternations of IK, marker placement and rigid fit.
        root: the free root offset solved with z (None: the arm's root is fixed).
        marker_bound: largest marker offset [m] (0: keypoints at the body origins).

    Raises:
        InvalidSynergyInput: ``marker_bound`` negative, or ``root`` with a bound <= 0 or
            a negative weight.
    """
    if not marker_bound >= 0.0:
        raise InvalidSynergyInput(
            f"marker_bound must be >= 0 m, got {marker_bound!r}", "marker_bound"
        )
    if root is not None and not (root.bound > 0.0 and root.weight >= 0.0):
        raise InvalidSynergyInput(
            f"root must have bound > 0 m and weight >= 0, got {root!r}", "root"
        )
    markers = np.zeros((len(FITTED), 3))
    solver = _Solver(robot, root, markers)
    nz = solver.nz
    sub = local[np.linspace(0, len(local) - 1, frames).astype(int)]
    q0 = coupling_of(robot).q(solver.start()[:nz])
    kp = model_keypoints(robot, q0, ("RightShoulder", "RightArm"))
    right = kp[1] - kp[0]
    up = np.array([0.0, 0.0, 1.0])
    x = right - (right @ up) * up
    x /= np.linalg.norm(x)
    R, t = np.column_stack([x, np.cross(up, x), up]), kp[0]
    x0 = solver.start()
    rms = np.inf
    for _ in range(rounds):
        target = sub @ R.T + t
        X = _solve_all(solver, target, x0)
        if marker_bound > 0:
            markers = _place_markers(solver, X, target, marker_bound)
            solver.markers = markers
        model = np.array(
            [model_keypoints(robot, coupling_of(robot).q(xx[:nz]), FITTED, markers) for xx in X]
        )
        if root is not None:
            model = model + X[:, None, nz:]
        A, B = sub.reshape(-1, 3), model.reshape(-1, 3)
        ca, cb = A.mean(axis=0), B.mean(axis=0)
        U, _, Vt = np.linalg.svd((A - ca).T @ (B - cb))
        D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
        R = (U @ D @ Vt).T
        t = cb - R @ ca
        rms = float(np.sqrt(np.mean(np.sum((A @ R.T + t - B) ** 2, axis=1))))
        x0 = X[0]
    return Calibration(R, t, rms, rounds, markers, root)


def fit_sequence(
    robot: Robot,
    seq: MocapSequence,
    calib: Calibration,
    *,
    cutoff: float = 6.0,
) -> ArmFit:
    """Per-frame IK of one sequence, then zero-phase smoothing (see the module doc).

    Args:
        robot: the (scaled) arm.
        seq: the capture.
        calib: from `calibrate` (its marker offsets and root offset are used; the root
            offset is solved per frame, smoothed like z and included in the residuals).
        cutoff: low-pass cut-off [Hz] (below the Nyquist frequency ``fps / 2``).

    Raises:
        InvalidSynergyInput: ``cutoff`` not in (0, fps/2).
    """
    if not 0.0 < cutoff < seq.fps / 2:
        raise InvalidSynergyInput(
            f"cutoff must be in (0, {seq.fps / 2:g}) Hz for {seq.fps:g} fps, got {cutoff!r}",
            "cutoff",
        )
    root = calib.root
    solver = _Solver(robot, root, calib.markers)
    nz = solver.nz
    targets = local_keypoints(seq.positions) @ calib.R.T + calib.t
    x0 = _solve_all(solver, targets[:1], solver.start())[0]
    x_raw = _solve_all(solver, targets, x0)
    from scipy.signal import butter, filtfilt  # heavy (scipy.stats): imported where used

    b, a = butter(2, cutoff / (seq.fps / 2))
    x = np.clip(filtfilt(b, a, x_raw, axis=0), solver.lo, solver.hi)

    def dist(X: np.ndarray) -> np.ndarray:
        P = np.array(
            [
                model_keypoints(robot, coupling_of(robot).q(xx[:nz]), FITTED, calib.markers)
                for xx in X
            ]
        )
        if root is not None:
            P = P + X[:, None, nz:]
        return np.asarray(np.linalg.norm(P - targets, axis=2))

    z_raw = x_raw[:, :nz]
    at_limit = np.any((z_raw <= solver.lo[:nz] + 1e-6) | (z_raw >= solver.hi[:nz] - 1e-6), axis=1)
    t = np.arange(len(x)) / seq.fps
    offset = x[:, nz:] if root is not None else np.zeros((len(x), 3))
    return ArmFit(
        seq.name, t, x[:, :nz], z_raw, targets, dist(x), dist(x_raw), at_limit, offset,
        calib.markers.copy(),
    )  # fmt: skip


def scale_factors(sequences: Sequence[MocapSequence], robot: Robot) -> dict[str, float]:
    """Per-segment factors (captured median length / model length) of `SEGMENTS`."""
    captured = segment_lengths(np.concatenate([s.positions for s in sequences]))
    model = model_segment_lengths(robot)
    return {s: captured[s] / model[s] for s in SEGMENTS}
