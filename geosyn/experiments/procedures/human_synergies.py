"""Synergies learned from human motion and carried to a robot (the paper's first open
challenge, `geosyn.synergies.human`).

The climbing capture of ``holosoma-retargeting`` (fetched and cached, see
`geosyn.synergies.human.data`) is fitted by the scaled MyoArm (per-frame IK in its coupled
coordinates), cut into point-to-point segments that are compared with the arm metric's
geodesics and with straight joint-space lines, analysed by exact PGA against PCA, and
carried to the config's robot: hand paths mapped in task space (scaled by the reach ratio,
lowered by `geosyn.synergies.human.transfer.fit_scale` until the robot can reach the path
and hold its postures against gravity within ``torque_margin`` of its torque limits;
mirrored for a left arm), per-frame kinematic retargeting as the baseline, geodesics of
the robot's own metric between its ends, the first ``track`` of them tracked by computed
torque in MuJoCo under a push on the hand.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field

from geosyn.controllers import ComputedTorque, GeodesicReference
from geosyn.experiments.procedures.base import Procedure, RunContext, register
from geosyn.experiments.run import build as B
from geosyn.experiments.schema import ExperimentConfig, JointVector, Strict
from geosyn.metrics.geodesic import Geodesic
from geosyn.sim import Push, Simulation
from geosyn.synergies.human import figures as fg
from geosyn.synergies.human import mocap_ik as ik
from geosyn.synergies.human import study as st
from geosyn.synergies.human import transfer as tr
from geosyn.synergies.human.data import climb_sequences


class HumanSynergiesParams(Strict):
    """Parameters of `HumanSynergies`: which capture (sequences, frames per sequence from
    the start; None: all), segments (most analysed), PGA (postures, k_max, refinement
    evaluations, RK4 steps), the robot's home posture [rad] and shoulder frame, tracking
    (segments tracked, computed-torque gains [1/s^2, 1/s], push on the hand [N]), the
    workspace scaling's torque margin and the left-right mirror."""

    sequences: list[Annotated[int, Field(ge=0, le=4)]] | None = Field(
        None, description="climbing sequences used, 0-4 (None: all five)"
    )
    frames: Annotated[int, Field(ge=60)] | None = Field(
        None, description="frames per sequence from its start (None: all)"
    )
    max_segments: Annotated[int, Field(ge=1)] | None = Field(
        None, description="most point-to-point segments analysed (None: all)"
    )
    pga_configs: Annotated[int, Field(ge=3, le=500)] = Field(
        30, description="recorded postures given to PGA and PCA (evenly spaced)"
    )
    k_max: Annotated[int, Field(ge=1, le=7)] = Field(
        5, description="largest number of synergies compared"
    )
    pga_evals: Annotated[int, Field(ge=0, le=1000)] = Field(
        6, description="cost evaluations of the exact-PGA refinement per k"
    )
    steps: Annotated[int, Field(ge=10, le=1000)] = Field(
        30, description="integration steps of each geodesic"
    )
    q_home: JointVector = Field(description="(nv,) robot home posture [rad]")
    shoulder_frame: str = Field(description="robot frame playing the human shoulder")
    track: Annotated[int, Field(ge=0)] = Field(
        20, description="transferred segments tracked in MuJoCo"
    )
    kp: Annotated[float, Field(gt=0)] = Field(
        400.0, description="computed-torque position gain [1/s^2]"
    )
    kd: Annotated[float, Field(gt=0)] = Field(
        40.0, description="computed-torque velocity gain [1/s]"
    )
    push: Annotated[float, Field(ge=0)] = Field(
        50.0, description="push on the robot's hand during each tracked segment [N]"
    )
    torque_margin: Annotated[float, Field(gt=0, le=1)] | None = Field(
        0.7,
        description="workspace scaling: largest share of each torque limit that holding the"
        " robot's postures against gravity may take (None: keep the reach ratio)",
    )
    mirror: bool = Field(
        False, description="carry the human right arm to a left arm (path mirrored left-right)"
    )


@register
class HumanSynergies(Procedure):
    """Human capture -> MyoArm joint angles -> geodesic segments, PGA -> robot, tracked."""

    kind = "human_synergies"
    sections = ("robot", "metric", "outputs", "params")
    description = "synergies from human motion capture (MyoArm), PGA vs PCA, transfer to a robot"
    Params = HumanSynergiesParams
    units = {
        "ik_median": "m",
        "ik_worst": "m",
        "geodesic_closer_in_z": "1",
        "geodesic_closer_hand": "1",
        "segments": "1",
        "pga_metric": "sqrt(kg m^2) rad",
        "pca_metric": "sqrt(kg m^2) rad",
        "pga_plain": "rad",
        "pca_plain": "rad",
        "hand_dev_median": "m",
        "energy_below_kinematic": "1",
        "tracking_rms_worst": "rad",
        "reach_scale": "1",
        "scale": "1",
        "tracking_saturated": "1",
    }

    @classmethod
    def check(cls, cfg: ExperimentConfig, params: Any, robot: Any) -> list[tuple[str, str]]:
        out = []
        if cfg.robot.plant != "model":
            out.append(
                (
                    "robot.plant",
                    "must be 'model': the transferred segments are tracked on geosyn's model",
                )
            )
        if len(params.q_home) != robot.nv:
            out.append(("params.q_home", f"must have nv={robot.nv} values"))
        if not robot.model.existFrame(params.shoulder_frame):
            out.append(("params.shoulder_frame", f"{params.shoulder_frame!r} is not a frame"))
        return out

    def run(self, ctx: RunContext) -> dict[str, np.ndarray]:
        p, robot = ctx.params, ctx.robot
        advance = ctx.progress(f"{ctx.config.name}: steps", 5)
        seqs, _ = climb_sequences()
        if p.sequences is not None:
            seqs = [seqs[i] for i in p.sequences]
        if p.frames is not None:
            seqs = [s._replace(positions=s.positions[: p.frames]) for s in seqs]
        subjects = st.scaled_arms(seqs)
        fits = st.fit_capture(seqs, subjects)
        advance()
        segs = st.segment_capture(seqs, subjects, fits, max_segments=p.max_segments)
        advance()
        sub = subjects[0]
        Z = np.concatenate([fits[i].z for i in sub.members])
        X = Z[np.linspace(0, len(Z) - 1, p.pga_configs).astype(int)]
        rows = st.pga_vs_pca_rows(sub.metric, X, p.k_max, evals=p.pga_evals, steps=p.steps)
        advance()
        metric = B.build_metric(ctx.config, robot)
        hmap, _, moved = st.transfer_capture(
            robot, metric, np.array(p.q_home), p.shoulder_frame, seqs, sub, fits, segs,
            torque_margin=p.torque_margin, mirror=p.mirror,
        )  # fmt: skip
        advance()
        rms, saturated = [], []
        for res in moved[: p.track]:
            ref = GeodesicReference(Geodesic(res.t, res.q_geodesic, res.v_geodesic), metric)
            duration = float(res.t[-1])
            kick = Push(robot.ee_frame, [p.push, 0.0, 0.0], start=duration / 3, duration=0.1)
            sim = Simulation(robot, ComputedTorque(robot, p.kp, p.kd, reference=ref),
                             disturbances=[kick])  # fmt: skip
            run = sim.run(res.q_geodesic[0], res.v_geodesic[0], duration=duration)
            rms.append(float(np.sqrt(np.mean(run.tracking_error**2))))
            saturated.append(float(run.saturated.any(axis=1).mean()))
        advance()
        ex = moved[0] if moved else None
        hands = [
            np.array([tr.hand_position(robot, q) for q in Q])
            if ex is not None
            else np.zeros((0, 3))
            for Q in ((ex.q_kinematic, ex.q_geodesic) if ex is not None else ((), ()))
        ]
        return {
            "ik_residual": np.concatenate([f.residual for f in fits]),
            "seg_geodesic_dev": np.array([s.geodesic_dev for s in segs]),
            "seg_line_dev": np.array([s.line_dev for s in segs]),
            "seg_geodesic_hand_dev": np.array([s.geodesic_hand_dev for s in segs]),
            "seg_line_hand_dev": np.array([s.line_hand_dev for s in segs]),
            "pga_rows": np.array([list(r) for r in rows], dtype=np.float64),
            "transfer_hand_dev": np.array([m.hand_dev_geodesic for m in moved]),
            "transfer_energy_geodesic": np.array([m.energy_geodesic for m in moved]),
            "transfer_energy_kinematic": np.array([m.energy_kinematic for m in moved]),
            "tracking_rms": np.array(rms),
            "tracking_saturated_ticks": np.array(saturated),
            "transfer_scale": np.array([hmap.reach_scale, hmap.scale]),
            "ik_root_offset": np.concatenate([f.root_offset for f in fits]),
            "example_target": ex.target if ex is not None else np.zeros((0, 3)),
            "example_kinematic": hands[0],
            "example_geodesic": hands[1],
        }

    def summarize(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray]
    ) -> dict[str, float]:
        r = results
        out = {
            "ik_median": float(np.median(r["ik_residual"])),
            "ik_worst": float(np.max(r["ik_residual"])),
            "segments": float(len(r["seg_line_dev"])),
            "geodesic_closer_in_z": float(np.sum(r["seg_geodesic_dev"] < r["seg_line_dev"])),
            "geodesic_closer_hand": float(
                np.sum(r["seg_geodesic_hand_dev"] < r["seg_line_hand_dev"])
            ),
        }
        for row in r["pga_rows"]:
            k = int(row[0])
            for j, name in enumerate(("pga_metric", "pca_metric", "pga_plain", "pca_plain")):
                out[f"k={k}.{name}"] = float(row[1 + j])
        if "transfer_scale" in r:
            out["transfer.reach_scale"] = float(r["transfer_scale"][0])
            out["transfer.scale"] = float(r["transfer_scale"][1])
        if len(r["transfer_hand_dev"]):
            out["transfer.hand_dev_median"] = float(np.median(r["transfer_hand_dev"]))
            out["transfer.energy_below_kinematic"] = float(
                np.sum(r["transfer_energy_geodesic"] < r["transfer_energy_kinematic"])
            )
        if len(r["tracking_rms"]):
            out["transfer.tracking_rms_worst"] = float(np.max(r["tracking_rms"]))
            out["transfer.tracking_saturated"] = float(np.sum(r["tracking_saturated_ticks"] > 0))
        return out

    def plot(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray], out_dir: Path
    ) -> list[Path]:
        r = results
        keys = ("k", "pga_metric", "pca_metric", "pga_plain", "pca_plain")
        rows = [dict(zip(keys, row[:5].tolist(), strict=True)) for row in r["pga_rows"]]
        paths = [
            fg.ik_residuals(r["ik_residual"], ik.FITTED, out_dir / "ik_residuals.png"),
            fg.pga_vs_pca(rows, out_dir / "pga_vs_pca.png"),
        ]
        if len(r["seg_line_dev"]):
            paths.append(
                fg.segment_fit(r["seg_geodesic_dev"], r["seg_line_dev"], out_dir / "segments.png")
            )
        if len(r["example_target"]):
            paths.append(
                fg.hand_paths(
                    r["example_target"],
                    r["example_kinematic"],
                    r["example_geodesic"],
                    out_dir / "transfer.png",
                    f"a human segment on {cfg.robot.name}",
                )  # fmt: skip
            )
        return paths
