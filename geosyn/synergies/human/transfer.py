"""Human arm segments carried to a robot: hand paths matched in task space, then geodesics.

Method (stated, after Klein et al. 2022's per-synergy transfer):

1. Task-space correspondence: the human wrist path (in the arm model's frame) is mapped to
   the robot's base frame by ``p_r = p_home + s R (p_h - p_mean)``: R turns the human's
   (forward, left, up) axes onto the robot's (x, y, z); ``p_mean`` is the mean human
   wrist position, ``p_home`` the robot's hand at its home posture, and ``s`` the ratio
   of the robot's shoulder-to-hand distance at home to the human's mean
   shoulder-to-wrist distance ("after scaling"). `fit_scale` then lowers ``s`` (never
   raises it) to the largest value for which the robot can follow the mapped path
   (workspace scaling): on evenly spaced frames, the kinematic retargeting reaches the
   targets (95th percentile of the hand error <= ``reach_tol``) and holding each of its
   postures against gravity takes at most ``torque_margin`` of every joint's torque
   limit (the rest is left to the motion, the feedback and a push). A geodesic of the
   kinetic-energy metric needs no torque but gravity's (M q'' + C q' = 0 along it), so
   slowing it down would not lower the torque: where a robot saturated, it was holding
   a posture its limits cannot hold.
2. Kinematic retargeting (the baseline, as GMR-style tools do): per-frame position IK of
   the robot's hand on the mapped path, joint limits as bounds, a small pull towards
   the home posture for the redundant joints, warm-started from the previous frame.
3. Geodesic transfer: the robot's configurations at a segment's two ends are those of
   the kinematic retargeting (so the hand matches the human's there); in between, the
   robot follows the geodesic of its own kinetic-energy metric between them (log map by
   shooting), traversed in the segment's duration. It is the energy-minimal path between
   the ends, so its path energy is at most the kinematic path's whenever the shooting
   finds the minimizing geodesic. Where the hand would stray from the human path, the
   segment is cut into a few geodesics through frames of the kinematic retargeting
   (`transfer_segment`), which keeps the energy bound piece by piece.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pinocchio as pin

from geosyn.metrics.base import Metric
from geosyn.metrics.geodesic import exp, log
from geosyn.metrics.geodesic.energy import path_energy
from geosyn.robots import Robot
from geosyn.synergies.errors import InvalidSynergyInput


class HandMap(NamedTuple):
    """``p_r = p_home + scale * R @ (p_h - p_mean)`` (see the module doc)."""

    R: np.ndarray  # (3, 3) human model frame -> robot base frame
    scale: float
    p_mean: np.ndarray  # (3,) mean human wrist [m]
    p_home: np.ndarray  # (3,) robot hand at home [m]
    reach_scale: float  # the reach ratio (``scale`` before `fit_scale`)

    def __call__(self, p_h: np.ndarray) -> np.ndarray:
        """(T, 3) robot hand targets of human wrist positions (T, 3) [m]."""
        return self.p_home + self.scale * (np.asarray(p_h) - self.p_mean) @ self.R.T


class Transferred(NamedTuple):
    """One segment on the robot, by kinematic retargeting and by a geodesic."""

    t: np.ndarray  # (T,) [s]
    target: np.ndarray  # (T, 3) mapped human wrist path [m]
    q_kinematic: np.ndarray  # (T, n) per-frame IK [rad]
    q_geodesic: np.ndarray  # (T, n) geodesic between the same ends, same duration [rad]
    v_geodesic: np.ndarray  # (T, n) its velocities [rad/s]
    hand_dev_kinematic: float  # median distance robot hand - target [m]
    hand_dev_geodesic: float  # [m]
    energy_kinematic: float  # path energy on the robot's metric
    energy_geodesic: float
    pieces: int  # geodesic pieces used


def hand_position(robot: Robot, q: np.ndarray) -> np.ndarray:
    """(3,) position of the robot's end-effector frame [m]."""
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    return np.array(data.oMf[robot.frame_id(robot.ee_frame)].translation)


def hand_map(
    robot: Robot,
    q_home: np.ndarray,
    shoulder_frame: str,
    human_wrist: np.ndarray,
    human_shoulder: np.ndarray,
    human_axes: np.ndarray,
) -> HandMap:
    """The task-space correspondence of the module doc.

    Args:
        robot: the robot.
        q_home: (n,) home posture [rad].
        shoulder_frame: the robot frame playing the shoulder (e.g. the second joint).
        human_wrist: (T, 3) human wrist positions [m].
        human_shoulder: (T, 3) human shoulder (glenohumeral) positions [m].
        human_axes: (3, 3) columns forward, left, up of the human in its model frame.
    """
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q_home)
    p_home = np.array(data.oMf[robot.frame_id(robot.ee_frame)].translation)
    p_sh = np.array(data.oMf[robot.frame_id(shoulder_frame)].translation)
    reach_h = float(np.mean(np.linalg.norm(human_wrist - human_shoulder, axis=1)))
    scale = float(np.linalg.norm(p_home - p_sh)) / reach_h
    return HandMap(human_axes.T.copy(), scale, human_wrist.mean(axis=0), p_home, scale)


class ScaleFit(NamedTuple):
    """How `fit_scale` chose the map's scale."""

    reach_scale: float  # the reach ratio
    scale: float  # the scale kept (<= reach_scale)
    reach_error_p95: float  # at that scale: 95th percentile of the hand error [m]
    gravity_ratio: float  # max over frames and joints of |g_j(q)| / tau_max_j
    frames: int  # frames checked
    trials: int  # scales tried


def _feasibility(
    robot: Robot, hmap: HandMap, wrist: np.ndarray, q_home: np.ndarray
) -> tuple[float, float]:
    """(95th percentile of the hand error [m], max |g| / tau_max) of the kinematic
    retargeting of ``wrist`` (N, 3) through ``hmap``."""
    Q, err = kinematic_retarget(robot, hmap(wrist), q_home)
    data = robot.model.createData()
    g = np.array([pin.computeGeneralizedGravity(robot.model, data, q) for q in Q])
    return float(np.percentile(err, 95)), float(np.max(np.abs(g) / robot.tau_max))


def fit_scale(
    robot: Robot,
    hmap: HandMap,
    human_wrist: np.ndarray,
    q_home: np.ndarray,
    *,
    torque_margin: float = 0.7,
    reach_tol: float = 0.005,
    frames: int = 200,
    trials: int = 8,
) -> tuple[HandMap, ScaleFit]:
    """Lower the map's scale until the robot can follow the path (see the module doc).

    Bisection on the scale between ``0`` and ``hmap.reach_scale`` (feasibility is
    monotone in practice: a smaller scale keeps the hand closer to its home posture).

    Args:
        robot: the robot (finite ``tau_max``).
        hmap: from `hand_map`.
        human_wrist: (T, 3) human wrist positions [m] (all the frames to be carried).
        q_home: (n,) home posture [rad].
        torque_margin: largest share of each joint's torque limit that holding a posture
            against gravity may take, in (0, 1].
        reach_tol: largest 95th-percentile hand error of the kinematic retargeting [m].
        frames: evenly spaced frames checked (per scale tried).
        trials: bisection steps.

    Returns:
        The map with the scale kept, and the record of the choice.

    Raises:
        InvalidSynergyInput: ``torque_margin`` not in (0, 1], ``reach_tol`` <= 0,
            ``frames`` < 2, or the home posture itself violates the margin.
    """
    if not 0.0 < torque_margin <= 1.0 or not reach_tol > 0 or frames < 2:
        raise InvalidSynergyInput(
            f"torque_margin in (0, 1], reach_tol > 0, frames >= 2 expected, got"
            f" {torque_margin!r}, {reach_tol!r}, {frames!r}",
            "torque_margin",
        )
    wrist = np.asarray(human_wrist)[np.linspace(0, len(human_wrist) - 1, frames).astype(int)]

    def ok(scale: float) -> tuple[bool, float, float]:
        e, g = _feasibility(robot, hmap._replace(scale=scale), wrist, q_home)
        return e <= reach_tol and g <= torque_margin, e, g

    good, e, g = ok(hmap.reach_scale)
    best = (hmap.reach_scale, e, g) if good else None
    lo, hi, done = 0.0, hmap.reach_scale, 1
    while best is None or best[0] < hmap.reach_scale:
        if done >= trials:
            break
        mid = 0.5 * (lo + hi)
        good, e, g = ok(mid)
        done += 1
        if good:
            best, lo = (mid, e, g), mid
        else:
            hi = mid
    if best is None:
        _, g0 = _feasibility(robot, hmap._replace(scale=0.0), wrist[:1], q_home)
        raise InvalidSynergyInput(
            f"no scale in (0, {hmap.reach_scale:.3g}] tried keeps the path reachable and the"
            f" gravity torques <= {torque_margin:g} x tau_max (at home: {g0:.3g} x)",
            "torque_margin",
        )
    scale, e, g = best
    fit = ScaleFit(hmap.reach_scale, scale, e, g, len(wrist), done)
    return hmap._replace(scale=scale), fit


def kinematic_retarget(
    robot: Robot,
    targets: np.ndarray,
    q_home: np.ndarray,
    *,
    smooth: float = 0.01,
    posture: float = 1e-3,
) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame position IK of the hand (the baseline of the module doc).

    The redundant joints are resolved by two small pulls: towards the previous frame's
    solution (``smooth``, the least joint motion per frame) and towards ``q_home``
    (``posture``); both cost a little hand accuracy (reported per frame).

    Args:
        robot: the robot.
        targets: (T, 3) hand positions [m].
        q_home: (n,) home posture [rad] (first guess and posture pull).
        smooth: weight of the pull towards the previous frame [m/rad].
        posture: weight of the pull towards ``q_home`` [m/rad].

    Returns:
        (T, n) joint positions [rad] and (T,) hand errors [m].
    """
    model, data = robot.model, robot.model.createData()
    fid = robot.frame_id(robot.ee_frame)
    lo = np.where(np.isfinite(robot.q_min), robot.q_min, -np.pi)
    hi = np.where(np.isfinite(robot.q_max), robot.q_max, np.pi)
    n = robot.nq

    def res(q: np.ndarray, p: np.ndarray, q_prev: np.ndarray) -> np.ndarray:
        pin.framesForwardKinematics(model, data, q)
        return np.concatenate(
            [data.oMf[fid].translation - p, smooth * (q - q_prev), posture * (q - q_home)]
        )

    def jac(q: np.ndarray, p: np.ndarray, q_prev: np.ndarray) -> np.ndarray:
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        J = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]
        return np.vstack([J, smooth * np.eye(n), posture * np.eye(n)])

    out, err = np.empty((len(targets), n)), np.empty(len(targets))
    q = np.clip(q_home, lo + 1e-6, hi - 1e-6)
    from scipy.optimize import least_squares  # heavy (~0.2 s): imported where used

    for i, p in enumerate(targets):
        sol = least_squares(
            res, q, jac=jac, bounds=(lo, hi), args=(p, q.copy()), xtol=1e-12, ftol=1e-12
        )
        q = sol.x
        out[i] = q
        err[i] = float(np.linalg.norm(sol.fun[:3]))
    return out, err


def _piecewise_geodesic(
    metric: Metric, ts: np.ndarray, q_kin: np.ndarray, pieces: int
) -> tuple[np.ndarray, np.ndarray]:
    """Geodesics between ``pieces + 1`` evenly spaced frames of ``q_kin``, in its timing."""
    knots = np.unique(np.linspace(0, len(ts) - 1, pieces + 1).round().astype(int))
    Q, V = [q_kin[:1]], [np.zeros((1, q_kin.shape[1]))]
    for a, b in zip(knots[:-1], knots[1:], strict=True):
        dt = float(ts[b] - ts[a])
        v = log(metric, q_kin[a], q_kin[b], v_init=q_kin[b] - q_kin[a])
        geo = exp(metric, q_kin[a], v / dt, duration=dt, steps=int(b - a))
        Q.append(geo.q[1:])
        V.append(geo.v[1:])
        V[-2][-1] = geo.v[0]  # the velocity leaving a knot is the new piece's
    return np.vstack(Q), np.vstack(V)


def transfer_segment(
    metric: Metric,
    robot: Robot,
    t: np.ndarray,
    target: np.ndarray,
    q_kin: np.ndarray,
    *,
    max_hand_dev: float = 0.01,
    max_pieces: int = 8,
) -> Transferred:
    """Geodesic transfer of one segment (see the module doc).

    One geodesic between the segment's ends; when the robot's hand strays more than
    ``max_hand_dev`` (median) farther from the mapped human path than the kinematic
    retargeting's own hand (which misses targets out of the robot's reach), the segment
    is cut at evenly
    spaced frames of the kinematic retargeting into 2, 4, ... ``max_pieces`` geodesics
    (each the energy-minimal path between its ends in its duration, so the total energy
    stays at most the kinematic path's; the velocity jumps at the cuts).

    Args:
        metric: the robot's metric (e.g. `KineticEnergyMetric`).
        robot: the robot.
        t: (T,) segment time stamps [s] (T >= 3).
        target: (T, 3) mapped human wrist path [m].
        q_kin: (T, n) kinematic retargeting of the segment [rad].
        max_hand_dev: median hand distance allowed beyond the kinematic retargeting's
            before cutting [m].
        max_pieces: most geodesic pieces.

    Raises:
        InvalidSynergyInput: inconsistent shapes.
        GeodesicNotFound: a log map between two knots did not converge.
    """
    T = len(t)
    if T < 3 or target.shape != (T, 3) or q_kin.shape != (T, robot.nq):
        raise InvalidSynergyInput(
            f"t (T,), target (T, 3), q_kin (T, {robot.nq}) with T >= 3 expected, got"
            f" {t.shape}, {target.shape}, {q_kin.shape}",
            "t",
        )
    ts = t - t[0]

    def dev(Q: np.ndarray) -> float:
        hand = np.array([hand_position(robot, q) for q in Q])
        return float(np.median(np.linalg.norm(hand - target, axis=1)))

    pieces, d_kin = 1, dev(q_kin)
    while True:
        q_geo, v_geo = _piecewise_geodesic(metric, ts, q_kin, min(pieces, T - 1))
        d = dev(q_geo)
        if d <= d_kin + max_hand_dev or pieces >= min(max_pieces, T - 1):
            break
        pieces *= 2
    return Transferred(
        ts,
        target,
        q_kin,
        q_geo,
        v_geo,
        d_kin,
        d,
        path_energy(metric, ts, q_kin),
        path_energy(metric, ts, q_geo),
        min(pieces, T - 1),
    )
