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


def _g1_right_arm():
    from geosyn.robots.files import example_robot_data_dir, load_file

    path = example_robot_data_dir() / "g1_description/urdf/g1_29dof_rev_1_0.urdf"
    sides = ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow", "wrist_roll")
    keep = [f"right_{j}_joint" for j in (*sides, "wrist_pitch", "wrist_yaw")]
    return load_file(path, keep_joints=keep, name="g1_right_arm")


def _builtin(name):
    def load():
        from geosyn.robots import load_robot

        return load_robot(name)

    return load


ROBOTS = {
    # name: (loader, home posture [rad], shoulder frame)
    "panda": (_builtin("panda"), [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785], "panda_joint2"),
    "talos_arm": (_builtin("talos_arm"), [0.3, 0.4, 0.0, -1.2, 0.0, 0.0, 0.0], "arm_left_2_joint"),
    "g1_arm": (_g1_right_arm, [0.0, -0.3, 0.0, 1.0, 0.0, 0.0, 0.0], "right_shoulder_roll_joint"),
}


def _human_axes(arm) -> np.ndarray:
    """Columns forward, left, up of the human arm model (forward: the forearm at 90 deg)."""
    robot = arm.robot
    lo, hi = ik.z_box(robot)
    z = np.clip(np.zeros(robot.coupling.nz), lo, hi)
    z[3] = np.pi / 2  # elbow flexion
    kp = ik.model_keypoints(robot, robot.coupling.q(z), ("RightForeArm", "RightHand"))
    up = np.array([0.0, 0.0, 1.0])
    fwd = kp[1] - kp[0]
    fwd = fwd - (fwd @ up) * up
    fwd /= np.linalg.norm(fwd)
    return np.column_stack([fwd, np.cross(up, fwd), up])


def stage_transfer(out: Path, robot_name: str, n_track: int, push: float) -> None:
    from geosyn.controllers import ComputedTorque, GeodesicReference
    from geosyn.metrics.geodesic.exp_map import Geodesic
    from geosyn.sim import Push, Simulation
    from geosyn.synergies.human import transfer as tr

    t0 = _clock()
    seqs, _ = climb_sequences()
    arms = _arms(seqs)
    arm = arms[0][0]
    group = [i for i in range(len(seqs)) if arms[i][2] == arms[0][2]]
    rows = json.loads((out / "segments.json").read_text())["rows"]
    loader, home, shoulder = ROBOTS[robot_name]
    robot = loader()
    metric = KineticEnergyMetric(robot)
    q_home = np.array(home)
    wrist, gh, per_seq = [], [], {}
    for i in group:
        z = np.load(out / f"{seqs[i].name}.npz")["z"]
        kp = np.array([ik.model_keypoints(arm.robot, arm.robot.coupling.q(zz),
                                          ("RightArm", "RightHand")) for zz in z])  # fmt: skip
        per_seq[seqs[i].name] = kp[:, 1]
        wrist.append(kp[:, 1])
        gh.append(kp[:, 0])
    hmap = tr.hand_map(robot, q_home, shoulder, np.concatenate(wrist), np.concatenate(gh),
                       _human_axes(arm))  # fmt: skip
    results, tracked = [], []
    examples: dict[str, np.ndarray] = {}
    fps = seqs[0].fps
    kin_cache = {}
    for r in rows:
        if r["sequence"] not in per_seq:
            continue
        seq = r["sequence"]
        if seq not in kin_cache:
            kin_cache[seq] = tr.kinematic_retarget(robot, hmap(per_seq[seq]), q_home)
        q_all, err = kin_cache[seq]
        a, b = r["start"], r["stop"]
        t = np.arange(b - a + 1) / fps
        res = tr.transfer_segment(metric, robot, t, hmap(per_seq[seq][a : b + 1]), q_all[a : b + 1])
        results.append({"sequence": seq, "start": a, "stop": b,
                        "hand_dev_kinematic_m": res.hand_dev_kinematic,
                        "hand_dev_geodesic_m": res.hand_dev_geodesic,
                        "energy_kinematic": res.energy_kinematic,
                        "energy_geodesic": res.energy_geodesic,
                        "kinematic_ik_error_median_m": float(np.median(err[a : b + 1])),
                        "pieces": res.pieces})  # fmt: skip
        if not examples:
            hands = [np.array([tr.hand_position(robot, q) for q in Q])
                     for Q in (res.q_kinematic, res.q_geodesic)]  # fmt: skip
            examples = {"target": res.target, "kinematic": hands[0], "geodesic": hands[1]}
            np.savez(out / f"transfer_{robot_name}_example.npz", **examples)
        if len(tracked) < n_track:
            ref = GeodesicReference(Geodesic(res.t, res.q_geodesic, res.v_geodesic), metric)
            ctl = ComputedTorque(robot, 400.0, 40.0, reference=ref)
            duration = float(res.t[-1])
            kick = Push(robot.ee_frame, [push, 0.0, 0.0], start=duration / 3, duration=0.1)
            sim = Simulation(robot, ctl, disturbances=[kick])
            out_sim = sim.run(res.q_geodesic[0], res.v_geodesic[0], duration=duration)
            e = out_sim.tracking_error
            tracked.append({"segment": len(results) - 1, "duration_s": duration,
                            "rms_rad": float(np.sqrt(np.mean(e**2))),
                            "max_rad": float(np.abs(e).max()),
                            "saturated_ticks": float(out_sim.saturated.any(axis=1).mean()),
                            "pieces": res.pieces,
                            "ref_speed_max_rad_s": float(np.abs(res.v_geodesic).max())})  # fmt: skip
    hk = np.array([x["hand_dev_kinematic_m"] for x in results])
    hg = np.array([x["hand_dev_geodesic_m"] for x in results])
    ek = np.array([x["energy_kinematic"] for x in results])
    eg = np.array([x["energy_geodesic"] for x in results])
    summary = {
        "robot": robot_name, "segments": len(results), "scale": hmap.scale,
        "hand_dev_geodesic_median_m": float(np.median(hg)),
        "hand_dev_geodesic_worst_m": float(hg.max()),
        "hand_dev_kinematic_median_m": float(np.median(hk)),
        "energy_geodesic_below_kinematic": int(np.sum(eg < ek)),
        "energy_ratio_quartiles": np.percentile(eg / ek, [25, 50, 75]).tolist(),
        "energy_ratio_worst": float(np.max(eg / ek)),
        "pieces_histogram": np.bincount([x["pieces"] for x in results]).tolist(),
        "tracked": len(tracked), "push_N": push,
        "tracking_rms_worst_rad": max((x["rms_rad"] for x in tracked), default=float("nan")),
        "tracking_rms_median_rad": float(np.median([x["rms_rad"] for x in tracked]))
        if tracked else float("nan"),
        "time": _since(t0),
    }  # fmt: skip
    print(json.dumps(summary, indent=1))
    (out / f"transfer_{robot_name}.json").write_text(
        json.dumps({"summary": summary, "rows": results, "tracked": tracked}, indent=1)
    )


def stage_figures(out: Path, docs: Path) -> None:
    from geosyn.synergies.human import figures as fg

    seqs, _ = climb_sequences()
    res = np.concatenate([np.load(out / f"{s.name}.npz")["residual"] for s in seqs])
    fg.ik_residuals(res, ik.FITTED, docs / "human_ik_residuals.png")
    rows = json.loads((out / "segments.json").read_text())["rows"]
    fg.segment_fit(np.array([r["geodesic_dev"] for r in rows]),
                   np.array([r["line_dev"] for r in rows]), docs / "human_segments.png")  # fmt: skip
    fg.pga_vs_pca(json.loads((out / "pga.json").read_text())["rows"], docs / "human_pga_vs_pca.png")
    ex = np.load(out / "transfer_panda_example.npz")
    fg.hand_paths(ex["target"], ex["kinematic"], ex["geodesic"], docs / "human_to_panda.png",
                  "a human climbing segment on the Panda")  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument(
        "--stage", choices=("ik", "segments", "pga", "transfer", "figures", "all"), default="all"
    )
    p.add_argument("--robot", choices=tuple(ROBOTS), default="panda")
    p.add_argument("--track", type=int, default=20, help="segments tracked in MuJoCo")
    p.add_argument("--push", type=float, default=50.0, help="push on the hand [N]")
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
    if a.stage in ("transfer", "all"):
        stage_transfer(a.out, a.robot, a.track, a.push)
    if a.stage in ("figures", "all"):
        stage_figures(a.out, Path("docs"))


if __name__ == "__main__":
    main()
