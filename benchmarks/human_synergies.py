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
from pathlib import Path

import numpy as np

from geosyn.metrics import KineticEnergyMetric
from geosyn.synergies.human import mocap_ik as ik
from geosyn.synergies.human import study as st
from geosyn.synergies.human.data import climb_sequences


def _clock() -> tuple[float, float]:
    return time.perf_counter(), time.process_time()


def _since(t0: tuple[float, float]) -> str:
    return f"{time.perf_counter() - t0[0]:.1f} s wall, {time.process_time() - t0[1]:.1f} s CPU"


def _subjects(seqs):
    return st.scaled_arms(seqs)


def stage_ik(out: Path, marker_bound: float, root: ik.RootOffset | None) -> None:
    t0 = _clock()
    seqs, prov = climb_sequences()
    subjects = _subjects(seqs)
    fits = st.fit_capture(seqs, subjects, marker_bound=marker_bound, root=root)
    report = {"provenance": prov._asdict(), "sequences": []}
    for i, (seq, fit) in enumerate(zip(seqs, fits, strict=True)):
        sub = st.subject_of(subjects, i)
        np.savez(out / f"{seq.name}.npz", t=fit.t, z=fit.z, z_raw=fit.z_raw,
                 residual=fit.residual, residual_raw=fit.residual_raw,
                 root_offset=fit.root_offset, markers=fit.markers)  # fmt: skip
        offset = np.linalg.norm(fit.root_offset, axis=1)
        entry = {
            "name": seq.name, "frames": len(fit.t), "scale": sub.arm.scale,
            "subject": sub.members[0],
            "marker_offsets_mm": dict(zip(ik.FITTED, np.round(1000 * np.linalg.norm(
                fit.markers, axis=1), 1).tolist(), strict=True)),
            "root_offset_median_m": float(np.median(offset)),
            "root_offset_max_m": float(offset.max()),
            "median_m": float(np.median(fit.residual)), "worst_m": float(fit.residual.max()),
            "median_per_keypoint_m": dict(zip(ik.FITTED, np.median(fit.residual, 0).tolist(),
                                              strict=True)),
        }  # fmt: skip
        report["sequences"].append(entry)
        print(json.dumps(entry))
    res = np.concatenate([f.residual for f in fits])
    raw = np.concatenate([f.residual_raw for f in fits])
    off = np.concatenate([np.linalg.norm(f.root_offset, axis=1) for f in fits])
    report["all"] = {
        "frames": int(len(res)),
        "marker_bound_m": marker_bound,
        "root_offset": root._asdict() if root is not None else None,
        "root_offset_quartiles_m": np.percentile(off, [25, 50, 75]).tolist(),
        "root_offset_max_m": float(off.max()),
        "p75_m": float(np.percentile(res, 75)),
        "median_m": float(np.median(res)),
        "worst_m": float(res.max()),
        "p95_m": float(np.percentile(res, 95)),
        "median_raw_m": float(np.median(raw)),
        "median_per_keypoint_m": dict(zip(ik.FITTED, np.median(res, axis=0).tolist(), strict=True)),
        "frames_with_a_coordinate_at_a_limit": float(
            np.concatenate([f.at_limit for f in fits]).mean()
        ),
        "time": _since(t0),
    }
    print(json.dumps(report["all"], indent=1))
    (out / "ik.json").write_text(json.dumps(report, indent=1))


def _fits(out: Path, seqs) -> list:
    """The stored IK results as ArmFit records (only t and z are used downstream)."""
    fits = []
    for seq in seqs:
        d = np.load(out / f"{seq.name}.npz")
        empty = np.zeros((0,))
        fits.append(ik.ArmFit(seq.name, d["t"], d["z"], d["z_raw"], empty, d["residual"],
                              d["residual_raw"], empty, d["root_offset"], d["markers"]))  # fmt: skip
    return fits


def stage_segments(out: Path) -> None:
    t0 = _clock()
    seqs, _ = climb_sequences()
    rows = st.segment_capture(seqs, _subjects(seqs), _fits(out, seqs))
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
    sub = _subjects(seqs)[0]
    Z = np.concatenate([np.load(out / f"{seqs[i].name}.npz")["z"] for i in sub.members])
    X = Z[np.linspace(0, len(Z) - 1, n_configs).astype(int)]
    rows = st.pga_vs_pca_rows(sub.metric, X, kmax, evals=evals, steps=steps)
    for r in rows:
        print(json.dumps(r._asdict()))
    summary = {"configurations": n_configs, "exact_max_evals": evals, "steps": steps,
               "rows": [r._asdict() for r in rows], "time": _since(t0)}  # fmt: skip
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
    # name: (loader, home posture [rad], shoulder frame, mirror: a left arm, kp, kd)
    # critically damped gains (kd = 2 sqrt(kp)); with kp 400 the Panda held the push to
    # <= 1e-2 rad RMS on 88 of 90 segments (the 0.1 s push is 20 % of a 0.5 s segment)
    "panda": (_builtin("panda"), [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785], "panda_joint2",
              False, 900.0, 60.0),
    "talos_arm": (_builtin("talos_arm"), [0.3, 0.4, 0.0, -1.2, 0.0, 0.0, 0.0], "arm_left_2_joint",
                  True, 400.0, 40.0),
    # the G1 arm's inertia is ~100 x smaller than the Panda's (M_77 2e-3 vs 0.11 kg m^2):
    # the same kp would give it 100 x less joint stiffness against the push; its wrist
    # pitched -0.5 rad at home keeps the push's moment on the 5 N m wrist pitch lower
    "g1_arm": (_g1_right_arm, [0.2, -0.3, 0.0, 0.5, 0.0, -0.5, 0.0], "right_shoulder_roll_joint",
               False, 40000.0, 400.0),
}  # fmt: skip


def stage_transfer(
    out: Path,
    robot_name: str,
    n_track: int,
    push: float,
    margin: float | None,
    mirror: bool | None,
    kp: float | None = None,
    kd: float | None = None,
) -> None:
    import pinocchio as pin

    from geosyn.controllers import ComputedTorque, GeodesicReference
    from geosyn.metrics.geodesic.exp_map import Geodesic
    from geosyn.sim import Push, Simulation
    from geosyn.synergies.human import transfer as tr
    from geosyn.synergies.human.segments import Segment

    t0 = _clock()
    seqs, _ = climb_sequences()
    sub = _subjects(seqs)[0]
    rows = [Segment(**r) for r in json.loads((out / "segments.json").read_text())["rows"]]
    loader, home, shoulder, left, kp_robot, kd_robot = ROBOTS[robot_name]
    left = left if mirror is None else mirror
    kp, kd = kp or kp_robot, kd or kd_robot
    robot = loader()
    metric = KineticEnergyMetric(robot)
    hmap, sfit, moved = st.transfer_capture(robot, metric, np.array(home), shoulder, seqs, sub,
                                            _fits(out, seqs), rows, torque_margin=margin,
                                            mirror=left)  # fmt: skip
    res0 = moved[0]
    hands = [np.array([tr.hand_position(robot, q) for q in Q])
             for Q in (res0.q_kinematic, res0.q_geodesic)]  # fmt: skip
    np.savez(out / f"transfer_{robot_name}_example.npz", target=res0.target,
             kinematic=hands[0], geodesic=hands[1])  # fmt: skip
    tracked = []
    for j, res in enumerate(moved[:n_track]):
        ref = GeodesicReference(Geodesic(res.t, res.q_geodesic, res.v_geodesic), metric)
        ctl = ComputedTorque(robot, kp, kd, reference=ref)
        data = robot.model.createData()
        grav = max(float(np.max(np.abs(pin.computeGeneralizedGravity(robot.model, data, q))
                                / robot.tau_max)) for q in res.q_geodesic)  # fmt: skip
        duration = float(res.t[-1])
        kick = Push(robot.ee_frame, [push, 0.0, 0.0], start=duration / 3, duration=0.1)
        run = Simulation(robot, ctl, disturbances=[kick]).run(
            res.q_geodesic[0], res.v_geodesic[0], duration=duration
        )
        e = run.tracking_error
        tracked.append({"segment": j, "duration_s": duration,
                        "rms_rad": float(np.sqrt(np.mean(e**2))),
                        "max_rad": float(np.abs(e).max()),
                        "saturated_ticks": float(run.saturated.any(axis=1).mean()),
                        "saturated_joints": np.flatnonzero(run.saturated.any(axis=0)).tolist(),
                        "gravity_over_tau_max": grav,
                        "pieces": res.pieces,
                        "ref_speed_max_rad_s": float(np.abs(res.v_geodesic).max())})  # fmt: skip
    hk = np.array([m.hand_dev_kinematic for m in moved])
    hg = np.array([m.hand_dev_geodesic for m in moved])
    ek = np.array([m.energy_kinematic for m in moved])
    eg = np.array([m.energy_geodesic for m in moved])
    summary = {
        "robot": robot_name, "segments": len(moved), "scale": hmap.scale,
        "mirror": left, "torque_margin": margin,
        "scale_fit": sfit._asdict() if sfit is not None else None,
        "hand_dev_geodesic_median_m": float(np.median(hg)),
        "hand_dev_geodesic_worst_m": float(hg.max()),
        "hand_dev_kinematic_median_m": float(np.median(hk)),
        "energy_geodesic_below_kinematic": int(np.sum(eg < ek)),
        "energy_ratio_quartiles": np.percentile(eg / ek, [25, 50, 75]).tolist(),
        "energy_ratio_worst": float(np.max(eg / ek)),
        "pieces_histogram": np.bincount([m.pieces for m in moved]).tolist(),
        "tracked": len(tracked), "push_N": push, "kp": kp, "kd": kd,
        "tracking_rms_worst_rad": max((x["rms_rad"] for x in tracked), default=float("nan")),
        "tracking_rms_median_rad": float(np.median([x["rms_rad"] for x in tracked]))
        if tracked else float("nan"),
        "tracked_saturating": int(sum(x["saturated_ticks"] > 0 for x in tracked)),
        "time": _since(t0),
    }  # fmt: skip
    print(json.dumps(summary, indent=1))
    rows_out = [{"hand_dev_kinematic_m": m.hand_dev_kinematic,
                 "hand_dev_geodesic_m": m.hand_dev_geodesic,
                 "energy_kinematic": m.energy_kinematic, "energy_geodesic": m.energy_geodesic,
                 "pieces": m.pieces} for m in moved]  # fmt: skip
    (out / f"transfer_{robot_name}.json").write_text(
        json.dumps({"summary": summary, "rows": rows_out, "tracked": tracked}, indent=1)
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
    p.add_argument("--track", type=int, default=1000, help="segments tracked (default: all)")
    p.add_argument("--push", type=float, default=50.0, help="push on the hand [N]")
    p.add_argument(
        "--margin",
        type=float,
        default=0.7,
        help="torque margin of the workspace scaling (<= 0: reach ratio kept)",
    )
    p.add_argument(
        "--mirror",
        choices=("auto", "yes", "no"),
        default="auto",
        help="mirror the path (auto: for left arms)",
    )
    p.add_argument(
        "--marker-bound",
        type=float,
        default=ik.MARKER_BOUND,
        help="largest keypoint marker offset [m] (0: body origins)",
    )
    p.add_argument(
        "--root-bound",
        type=float,
        default=0.0,
        help="free root offset bound per axis [m] (0: root fixed)",
    )
    p.add_argument("--root-weight", type=float, default=ik.RootOffset().weight)
    p.add_argument("--kp", type=float, help="computed-torque gain [1/s^2] (default: per robot)")
    p.add_argument("--kd", type=float, help="computed-torque gain [1/s] (default: per robot)")
    p.add_argument("--out", type=Path, default=Path("benchmarks/data/human_synergies"))
    p.add_argument("--configs", type=int, default=30)
    p.add_argument("--kmax", type=int, default=5)
    p.add_argument("--evals", type=int, default=6)
    p.add_argument("--steps", type=int, default=30)
    a = p.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    if a.stage in ("ik", "all"):
        root = ik.RootOffset(a.root_bound, a.root_weight) if a.root_bound > 0 else None
        stage_ik(a.out, a.marker_bound, root)
    if a.stage in ("segments", "all"):
        stage_segments(a.out)
    if a.stage in ("pga", "all"):
        stage_pga(a.out, a.configs, a.kmax, a.evals, a.steps)
    if a.stage in ("transfer", "all"):
        for name in ROBOTS if a.stage == "all" else (a.robot,):
            mirror = None if a.mirror == "auto" else a.mirror == "yes"
            margin = a.margin if a.margin > 0 else None
            stage_transfer(a.out, name, a.track, a.push, margin, mirror, a.kp, a.kd)
    if a.stage in ("figures", "all"):
        stage_figures(a.out, Path("docs"))


if __name__ == "__main__":
    main()
