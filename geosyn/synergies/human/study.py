"""The human-synergy study's steps on whole data sets (used by the built-in experiment
``human_synergies`` and ``benchmarks/human_synergies.py``).

1. `scaled_arms`: one scaled MyoArm per captured skeleton (sequences grouped by their
   segment lengths to the millimetre).
2. `fit_capture`: calibration and per-frame IK of each sequence.
3. `segment_capture`: point-to-point segments vs geodesics and straight lines.
4. `pga_vs_pca_rows`: exact PGA vs PCA at k = 1..k_max, errors under the metric and in
   plain coordinates.
5. `transfer_capture`: the segments on a robot (`geosyn.synergies.human.transfer`).
Closed-loop tracking in MuJoCo lives in the experiment (the synergy layer does not simulate).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from geosyn.metrics import CoupledMetric, KineticEnergyMetric
from geosyn.metrics.base import Metric
from geosyn.metrics.geodesic import exp
from geosyn.metrics.geodesic.energy import distance
from geosyn.robots import Robot
from geosyn.synergies.human import mocap_ik as ik
from geosyn.synergies.human import segments as sg
from geosyn.synergies.human import transfer as tr
from geosyn.synergies.human.data import MocapSequence
from geosyn.synergies.human.myoarm import HumanArm, load_myoarm
from geosyn.synergies.pga import pca_synergies, pga


class Subject(NamedTuple):
    """A captured skeleton: its sequences and its scaled arm."""

    members: tuple[int, ...]  # indices of its sequences
    arm: HumanArm
    metric: CoupledMetric  # the arm's pull-back kinetic-energy metric on z


def scaled_arms(seqs: Sequence[MocapSequence]) -> list[Subject]:
    """One scaled MyoArm per skeleton (see the module doc); loading warnings silenced
    (the arm's couplings and default velocity limits are stated by `load_myoarm`)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        base = load_myoarm().robot
        groups: dict[tuple[float, ...], list[int]] = {}
        for i, s in enumerate(seqs):
            key = tuple(round(v, 3) for v in ik.segment_lengths(s.positions).values())
            groups.setdefault(key, []).append(i)
        out = []
        for members in groups.values():
            arm = load_myoarm(scale=ik.scale_factors([seqs[i] for i in members], base))
            coupling = ik.coupling_of(arm.robot)
            metric = CoupledMetric(KineticEnergyMetric(arm.robot), coupling)
            out.append(Subject(tuple(members), arm, metric))
    return out


def subject_of(subjects: Sequence[Subject], index: int) -> Subject:
    """The subject of sequence ``index``."""
    return next(s for s in subjects if index in s.members)


def fit_capture(
    seqs: Sequence[MocapSequence],
    subjects: Sequence[Subject],
    *,
    calib_frames: int = 120,
    rounds: int = 6,
    cutoff: float = 6.0,
    marker_bound: float = ik.MARKER_BOUND,
    root: ik.RootOffset | None = None,
) -> list[ik.ArmFit]:
    """Calibration (marker placement within ``marker_bound`` [m], the free root offset
    ``root``) and IK of every sequence on its subject's arm (`mocap_ik`)."""
    fits = []
    for i, seq in enumerate(seqs):
        robot = subject_of(subjects, i).arm.robot
        local = ik.local_keypoints(seq.positions)
        frames = min(calib_frames, len(local))
        calib = ik.calibrate(
            robot, local, frames=frames, rounds=rounds, root=root, marker_bound=marker_bound
        )
        fits.append(ik.fit_sequence(robot, seq, calib, cutoff=cutoff))
    return fits


def segment_capture(
    seqs: Sequence[MocapSequence],
    subjects: Sequence[Subject],
    fits: Sequence[ik.ArmFit],
    *,
    max_segments: int | None = None,
) -> list[sg.Segment]:
    """Segments of every sequence compared with geodesics and lines (at most
    ``max_segments`` in all, in sequence order)."""
    rows: list[sg.Segment] = []
    for i, (seq, fit) in enumerate(zip(seqs, fits, strict=True)):
        sub = subject_of(subjects, i)
        hand, speed = sg.hand_speed(sub.arm.robot, fit.z, seq.fps)
        for a, b in sg.split(speed, hand, seq.fps):
            if max_segments is not None and len(rows) >= max_segments:
                return rows
            rows.append(sg.compare_segment(sub.metric, sub.arm.robot, fit.z, seq.name, a, b))
    return rows


class PGARow(NamedTuple):
    """PGA vs PCA at one k."""

    k: int
    pga_metric: float  # mean distance under the metric [sqrt(kg m^2) rad]
    pca_metric: float
    pga_plain: float  # mean Euclidean distance in z [rad]
    pca_plain: float
    pga_variance_ratio: float
    pca_variance_ratio: float
    exact_before: float  # exact PGA cost at the tangent-PCA initialisation [rad^2 G]
    exact_after: float  # after the refinement
    mean_iterations: int


def pga_vs_pca_rows(
    metric: Metric, X: np.ndarray, k_max: int, *, evals: int = 6, steps: int = 30
) -> list[PGARow]:
    """Exact PGA (tangent PCA at the Fréchet mean, refined by ``evals`` evaluations) vs
    PCA on configurations ``X`` (N, n), k = 1..k_max."""
    pca = pca_synergies(X, k_max)
    rows = []
    for k in range(1, k_max + 1):
        res = pga(metric, X, k, exact=True, steps=steps, exact_max_evals=evals)
        C = res.log_vectors @ metric.G(res.mean) @ res.V
        X_pga = np.array([exp(metric, res.mean, res.V @ c, steps=steps).q[-1] for c in C])
        P = pca.components[:, :k]
        X_pca = pca.mean + (X - pca.mean) @ P @ P.T
        d_pca = [distance(metric, a, b, steps=steps) for a, b in zip(X_pca, X, strict=True)]
        before, after = res.exact_cost or (np.nan, np.nan)
        rows.append(
            PGARow(
                k,
                float(res.reconstruction_error[-1]),
                float(np.mean(d_pca)),
                float(np.mean(np.linalg.norm(X_pga - X, axis=1))),
                float(pca.reconstruction_error[k - 1]),
                float(res.explained_variance_ratio.sum()),
                float(pca.explained_variance_ratio[:k].sum()),
                float(before),
                float(after),
                int(res.mean_iterations),
            )
        )
    return rows


def transfer_capture(
    robot: Robot,
    metric: Metric,
    q_home: np.ndarray,
    shoulder_frame: str,
    seqs: Sequence[MocapSequence],
    subject: Subject,
    fits: Sequence[ik.ArmFit],
    segments: Sequence[sg.Segment],
    *,
    torque_margin: float | None = 0.7,
    mirror: bool = False,
) -> tuple[tr.HandMap, tr.ScaleFit | None, list[tr.Transferred]]:
    """The segments of one subject's sequences on a robot (see `transfer`).

    Args:
        torque_margin: `transfer.fit_scale`'s margin (None: keep the reach ratio).
        mirror: carry the human right arm to a left arm (the path mirrored left-right).

    Returns:
        The task-space map, how its scale was chosen (None without ``torque_margin``)
        and one `Transferred` per segment of the subject.
    """
    arm = subject.arm.robot
    coupling = ik.coupling_of(arm)
    names = [seqs[i].name for i in subject.members]
    wrist: dict[str, np.ndarray] = {}
    shoulders = []
    for i in subject.members:
        kp = np.array(
            [ik.model_keypoints(arm, coupling.q(z), ("RightArm", "RightHand")) for z in fits[i].z]
        )
        wrist[seqs[i].name] = kp[:, 1]
        shoulders.append(kp[:, 0])
    hmap = tr.hand_map(
        robot,
        q_home,
        shoulder_frame,
        np.concatenate(list(wrist.values())),
        np.concatenate(shoulders),
        human_axes(subject.arm, mirror=mirror),
    )
    all_wrist = np.concatenate(list(wrist.values()))
    scale_fit = None
    if torque_margin is not None:
        hmap, scale_fit = tr.fit_scale(robot, hmap, all_wrist, q_home, torque_margin=torque_margin)
    kin = {n: tr.kinematic_retarget(robot, hmap(wrist[n]), q_home)[0] for n in names}
    out = []
    fps = seqs[subject.members[0]].fps
    for s in segments:
        if s.sequence not in kin:
            continue
        t = np.arange(s.stop - s.start + 1) / fps
        target = hmap(wrist[s.sequence][s.start : s.stop + 1])
        out.append(
            tr.transfer_segment(metric, robot, t, target, kin[s.sequence][s.start : s.stop + 1])
        )
    return hmap, scale_fit, out


def human_axes(arm: HumanArm, *, mirror: bool = False) -> np.ndarray:
    """(3, 3) columns forward, left, up of the human arm model (forward: the forearm's
    horizontal direction with the elbow flexed 90 degrees, up: +z); with ``mirror``,
    the second column points right instead (a right arm's motion carried to a left
    arm, mirrored in the sagittal plane)."""
    robot = arm.robot
    coupling = ik.coupling_of(robot)
    lo, hi = ik.z_box(robot)
    z = np.clip(np.zeros(coupling.nz), lo, hi)
    z[coupling.independent.index("elbow_flexion_r")] = np.pi / 2
    kp = ik.model_keypoints(robot, coupling.q(z), ("RightForeArm", "RightHand"))
    up = np.array([0.0, 0.0, 1.0])
    fwd = kp[1] - kp[0]
    fwd = fwd - (fwd @ up) * up
    fwd /= np.linalg.norm(fwd)
    left = np.cross(up, fwd)
    return np.column_stack([fwd, -left if mirror else left, up])
