"""Human arm synergies from motion capture, end to end (issue 25): numbers for RESULTS.md.

Stages (results cached in --out as NPZ/JSON; each stage prints what it measured):
  ik        scale the MyoArm per skeleton, calibrate, per-frame IK of all 12,939 frames
  segments  velocity-minimum segments vs geodesics and straight lines on the arm metric
  pga       exact PGA vs PCA at k = 1..5 on a subsample of the recorded configurations

Run: nice -n 10 .venv/bin/python benchmarks/human_synergies.py --stage all
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np

from geosyn.metrics import CoupledMetric, KineticEnergyMetric
from geosyn.metrics.geodesic import exp
from geosyn.metrics.geodesic.energy import distance
from geosyn.synergies import pca_synergies, pga
from geosyn.synergies.human import mocap_ik as ik
from geosyn.synergies.human import segments as sg
from geosyn.synergies.human.data import climb_sequences
from geosyn.synergies.human.myoarm import load_myoarm


def _clock() -> tuple[float, float]:
    return time.perf_counter(), time.process_time()


def _since(t0: tuple[float, float]) -> str:
    return f"{time.perf_counter() - t0[0]:.1f} s wall, {time.process_time() - t0[1]:.1f} s CPU"


def _arms(seqs):
    warnings.simplefilter("ignore")
    base = load_myoarm().robot
    groups: dict[tuple, list[int]] = {}
    for i, s in enumerate(seqs):
        key = tuple(round(v, 3) for v in ik.segment_lengths(s.positions).values())
        groups.setdefault(key, []).append(i)
    arms = {}
    for members in groups.values():
        factors = ik.scale_factors([seqs[i] for i in members], base)
        arm = load_myoarm(scale=factors)
        for i in members:
            arms[i] = (arm, factors, members[0])
    return arms


def stage_ik(out: Path) -> None:
    t0 = _clock()
    seqs, prov = climb_sequences()
    arms = _arms(seqs)
    report = {"provenance": prov._asdict(), "sequences": []}
    all_res, all_raw, limits = [], [], []
    for i, seq in enumerate(seqs):
        arm, factors, group = arms[i]
        t1 = _clock()
        calib = ik.calibrate(arm.robot, ik.local_keypoints(seq.positions), frames=120, rounds=6)
        fit = ik.fit_sequence(arm.robot, seq, calib)
        np.savez(out / f"{seq.name}.npz", t=fit.t, z=fit.z, z_raw=fit.z_raw,
                 residual=fit.residual, residual_raw=fit.residual_raw, group=group)  # fmt: skip
        all_res.append(fit.residual)
        all_raw.append(fit.residual_raw)
        limits.append(fit.at_limit)
        entry = {
            "name": seq.name, "frames": len(fit.t), "scale": factors, "group": group,
            "calibration_rms_m": calib.rms,
            "median_m": float(np.median(fit.residual)), "worst_m": float(fit.residual.max()),
            "median_per_keypoint_m": dict(zip(ik.FITTED, np.median(fit.residual, 0).tolist(),
                                              strict=True)),
            "time": _since(t1),
        }  # fmt: skip
        report["sequences"].append(entry)
        print(json.dumps(entry))
    res, raw = np.concatenate(all_res), np.concatenate(all_raw)
    report["all"] = {
        "frames": int(len(res)),
        "median_m": float(np.median(res)),
        "worst_m": float(res.max()),
        "p95_m": float(np.percentile(res, 95)),
        "median_raw_m": float(np.median(raw)),
        "median_per_keypoint_m": dict(zip(ik.FITTED, np.median(res, axis=0).tolist(), strict=True)),
        "frames_with_a_coordinate_at_a_limit": float(np.concatenate(limits).mean()),
        "time": _since(t0),
    }
    print(json.dumps(report["all"], indent=1))
    (out / "ik.json").write_text(json.dumps(report, indent=1))


def stage_segments(out: Path) -> None:
    t0 = _clock()
    seqs, _ = climb_sequences()
    arms = _arms(seqs)
    metrics = {}
    rows = []
    for i, seq in enumerate(seqs):
        arm, _, group = arms[i]
        if group not in metrics:
            metrics[group] = CoupledMetric(KineticEnergyMetric(arm.robot), arm.robot.coupling)
        z = np.load(out / f"{seq.name}.npz")["z"]
        hand, speed = sg.hand_speed(arm.robot, z, seq.fps)
        for a, b in sg.split(speed, hand, seq.fps):
            rows.append(sg.compare_segment(metrics[group], arm.robot, z, seq.name, a, b))
    geo = np.array([r.geodesic_dev for r in rows])
    line = np.array([r.line_dev for r in rows])
    hg = np.array([r.geodesic_hand_dev for r in rows])
    hl = np.array([r.line_hand_dev for r in rows])
    summary = {
        "segments": len(rows),
        "log_converged": int(sum(r.geodesic_ok for r in rows)),
        "geodesic_closer_in_z": int(np.sum(geo < line)),
        "geodesic_closer_hand": int(np.sum(hg < hl)),
        "z_dev_geodesic_rad_quartiles": np.percentile(geo, [25, 50, 75]).tolist(),
        "z_dev_line_rad_quartiles": np.percentile(line, [25, 50, 75]).tolist(),
        "ratio_geodesic_over_line_quartiles": np.percentile(geo / line, [25, 50, 75]).tolist(),
        "hand_dev_geodesic_m_quartiles": np.percentile(hg, [25, 50, 75]).tolist(),
        "hand_dev_line_m_quartiles": np.percentile(hl, [25, 50, 75]).tolist(),
        "travel_m_quartiles": np.percentile([r.travel for r in rows], [25, 50, 75]).tolist(),
        "time": _since(t0),
    }
    print(json.dumps(summary, indent=1))
    (out / "segments.json").write_text(
        json.dumps({"summary": summary, "rows": [r._asdict() for r in rows]}, indent=1)
    )


def stage_pga(out: Path, n_configs: int, kmax: int, evals: int, steps: int) -> None:
    t0 = _clock()
    seqs, _ = climb_sequences()
    arms = _arms(seqs)
    arm = arms[0][0]
    group = [i for i in range(len(seqs)) if arms[i][2] == arms[0][2]]
    Z = np.concatenate([np.load(out / f"{seqs[i].name}.npz")["z"] for i in group])
    X = Z[np.linspace(0, len(Z) - 1, n_configs).astype(int)]
    metric = CoupledMetric(KineticEnergyMetric(arm.robot), arm.robot.coupling)
    pca = pca_synergies(X, kmax)
    rows = []
    for k in range(1, kmax + 1):
        t1 = _clock()
        res = pga(metric, X, k, exact=True, steps=steps, exact_max_evals=evals)
        G = metric.G(res.mean)
        C = res.log_vectors @ G @ res.V
        X_pga = np.array([exp(metric, res.mean, res.V @ c, steps=steps).q[-1] for c in C])
        P = pca.components[:, :k]
        X_pca = pca.mean + (X - pca.mean) @ P @ P.T
        d_pca = [distance(metric, a, b, steps=steps) for a, b in zip(X_pca, X, strict=True)]
        row = {
            "k": k,
            "pga_metric": float(res.reconstruction_error[-1]),
            "pca_metric": float(np.mean(d_pca)),
            "pga_plain_rad": float(np.mean(np.linalg.norm(X_pga - X, axis=1))),
            "pca_plain_rad": float(pca.reconstruction_error[k - 1]),
            "pga_variance_ratio": float(res.explained_variance_ratio.sum()),
            "pca_variance_ratio": float(pca.explained_variance_ratio[:k].sum()),
            "exact_cost_before_after": list(res.exact_cost or (np.nan, np.nan)),
            "mean_iterations": res.mean_iterations,
            "time": _since(t1),
        }
        rows.append(row)
        print(json.dumps(row))
    summary = {"configurations": n_configs, "exact_max_evals": evals, "steps": steps,
               "rows": rows, "time": _since(t0)}  # fmt: skip
    (out / "pga.json").write_text(json.dumps(summary, indent=1))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--stage", choices=("ik", "segments", "pga", "all"), default="all")
    p.add_argument("--out", type=Path, default=Path("benchmarks/data/human_synergies"))
    p.add_argument("--configs", type=int, default=40)
    p.add_argument("--kmax", type=int, default=5)
    p.add_argument("--evals", type=int, default=10)
    p.add_argument("--steps", type=int, default=40)
    a = p.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    if a.stage in ("ik", "all"):
        stage_ik(a.out)
    if a.stage in ("segments", "all"):
        stage_segments(a.out)
    if a.stage in ("pga", "all"):
        stage_pga(a.out, a.configs, a.kmax, a.evals, a.steps)


if __name__ == "__main__":
    main()
