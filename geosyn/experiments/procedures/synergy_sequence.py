"""A task as a sequence of geodesic synergies: Cartesian goals reached one after the other.

Each goal is reached from the previous segment's end by a combination of the config's
synergies (transported to the segment's start, weights by `reach`, every sample inside
the joint limits; a goal missed by more than ``params.reach_tol`` fails, naming its
segment: `segments.task_sequence`); the segments meet at rest
(`geosyn.synergies.sequence`). Among the scene's obstacles, a segment whose geodesic comes
closer than `segments.CLEARANCE` to one (on the robot file's own collision geometry) is the
planner's minimum-energy collision-free path instead (`segments.avoiding_sequence`). The
baseline is the straight joint-space line through the same configurations with the same
time law. Both are tracked in MuJoCo by every configured controller; a run whose robot
touches an obstacle counts as failed, with the contact as reason.

Reported: kinetic energy of each planned motion (``energy``: the paths at constant speed
in their own parameter, which the geodesic minimises, and the geodesic's saving;
``timed_energy``: with the rest-to-rest time law), the jumps of
position/velocity/acceleration at the junctions, each segment's geodesic residual, the
reach errors, and per tracked run the effort, RMS tracking error, final hand error and
minimum clearance to the scene's obstacles. ``--video`` films every tracked run with the
goals drawn (``video_markers``, `geosyn.experiments.results.run_video`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field

from geosyn.controllers import JointTrajectoryReference
from geosyn.experiments.procedures.base import Procedure, RunContext, check_required, register
from geosyn.experiments.procedures.common import (
    Duration,
    Steps,
    robot_and_metric,
    track_with_each_controller,
)
from geosyn.experiments.procedures.outcomes import contact_reason, fail_run
from geosyn.experiments.procedures.segments import avoiding_sequence, task_sequence
from geosyn.experiments.results.plots import COLORS, figure, save
from geosyn.experiments.results.run_video import MARKERS
from geosyn.experiments.run import build as B
from geosyn.experiments.schema import ExperimentConfig, PositiveFloat, Strict, Vec3
from geosyn.robots.kinematics import frame_positions
from geosyn.synergies.sequence import SynergySequence, straight_sequence

PLANS = ("geodesic", "straight")


class SynergySequenceParams(Strict):
    """Parameters of `SynergySequenceProcedure`.

    Attributes:
        targets: (K, 3) hand goals, reached in turn [m].
        durations: time of each segment, or one for all [s].
        steps: RK4 steps of each geodesic (path samples - 1).
        sample_dt: sample period of the tracked reference [s].
        settle: simulated time after the motion [s].
        reach_tol: largest distance of the hand from a goal [m].
        plan_budget: the planner's time budget per segment [s].
    """

    targets: Annotated[list[Vec3], Field(min_length=1)]
    durations: PositiveFloat | Annotated[list[PositiveFloat], Field(min_length=1)] = 1.0
    steps: Steps = 200
    sample_dt: Annotated[float, Field(gt=0.0, le=0.05)] = 0.005
    settle: Duration = 0.3
    reach_tol: PositiveFloat = 1e-3
    plan_budget: Duration = 10.0

    def segment_durations(self) -> list[float]:
        """Duration of each segment [s]."""
        if isinstance(self.durations, list):
            return list(self.durations)
        return [self.durations] * len(self.targets)


def reference_of(seq: SynergySequence, dt: float) -> tuple[JointTrajectoryReference, np.ndarray]:
    """(the C2 reference through samples of ``seq`` every ``dt``, those samples' t)."""
    t, q, v, a = seq.trajectory(dt)
    return JointTrajectoryReference(t, q, v, a), t


@register
class SynergySequenceProcedure(Procedure):
    """Goals reached by a sequence of synergy geodesics vs straight lines, tracked."""

    kind = "synergy_sequence"
    sections = (
        "robot", "metric", "scene", "synergies", "controllers", "disturbances", "simulation",
        "outputs", "params",
    )  # fmt: skip
    description = "a task as a sequence of geodesic synergies (rest at the goals) vs straight lines"
    Params = SynergySequenceParams
    units = {
        "energy": "J s",
        "energy_saving": "%",
        "max_velocity_jump": "rad/s",
        "max_residual": "rad",
        "max_reach_error": "m",
        "final_hand_error": "m",
        "planned_clearance": "m",
    }

    @classmethod
    def check(cls, cfg: ExperimentConfig, params: Any, robot: Any) -> list[tuple[str, str]]:
        out = check_required(cfg, "synergies", "controllers")
        if isinstance(params.durations, list) and len(params.durations) != len(params.targets):
            out.append(("params.durations", f"one per target ({len(params.targets)})"))
        return out

    def run(self, ctx: RunContext) -> dict[str, np.ndarray]:
        cfg, robot, p = ctx.config, ctx.robot, ctx.params
        metric = B.build_metric(cfg, robot, scene=ctx.scene)
        syns = B.build_synergies(cfg, metric, robot)
        frame = getattr(cfg.synergies, "frame", None) or robot.ee_frame
        targets = np.array(p.targets)
        durations = p.segment_durations()
        advance = ctx.progress(f"{cfg.name}: plans and runs", 1 + 2 * len(cfg.controllers))
        names = [f"to goal {i}" for i in range(len(targets))]
        task = task_sequence(
            syns, targets, frame, robot, durations, steps=p.steps, tol=p.reach_tol, names=names
        )
        geo, how = avoiding_sequence(
            [metric] * len(targets), task.waypoints, durations, ctx.scene.obstacles,
            steps=p.steps, budget=p.plan_budget, seed=cfg.seed, names=names,
            geodesics=task.segments,
        )  # fmt: skip
        lin = straight_sequence(geo.waypoints, durations, steps=p.steps)
        advance()
        out: dict[str, np.ndarray] = {
            "targets": targets,
            MARKERS: targets,  # the goals, shown in the videos
            "waypoints": geo.waypoints,
            "junction_times": geo.junction_times,
            "junction_jumps": geo.junction_jumps(),
            # NaN: a planned segment that is not a geodesic
            "residuals": np.array(
                [np.nan if s.metric is None else s.geodesic_residual() for s in geo.segments]
            ),
            "reach_errors": np.array([s.reach_error for s in task.segments]),
            "weights": np.array([s.weights for s in task.segments]),
            "segment_planned": np.array([float(h.planned) for h in how]),
            "segment_clearance": np.array([h.clearance for h in how]),
        }
        duration = geo.duration + p.settle
        for name, seq in zip(PLANS, (geo, lin), strict=True):
            ref, _ = reference_of(seq, p.sample_dt)
            t, q, v, _ = seq.trajectory(p.sample_dt)
            out[f"{name}__t"], out[f"{name}__q"], out[f"{name}__v"] = t, q, v
            out[f"{name}__hand"] = frame_positions(robot, q, frame)
            out[f"{name}__energy"] = np.array(seq.path_energy(metric))
            out[f"{name}__timed_energy"] = np.array(seq.energy(metric))
            runs = track_with_each_controller(
                cfg, ctx.scene, metric, ref, q[0], v[0], f"{name}_", advance, duration=duration
            )
            for prefix in [k[: -len("__status")] for k in runs if k.endswith("__status")]:
                if (reason := contact_reason(B.sim_view(runs, prefix))) is not None:
                    fail_run(runs, prefix, reason)
            out |= runs
        return out

    def summarize(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray]
    ) -> dict[str, float]:
        robot, _ = robot_and_metric(cfg)
        frame = getattr(cfg.synergies, "frame", None) or robot.ee_frame
        e_geo, e_lin = float(results["geodesic__energy"]), float(results["straight__energy"])
        out: dict[str, float] = {
            "geodesic.energy": e_geo,
            "straight.energy": e_lin,
            "geodesic.timed_energy": float(results["geodesic__timed_energy"]),
            "straight.timed_energy": float(results["straight__timed_energy"]),
            "energy_saving": 100.0 * (1.0 - e_geo / e_lin),
            "max_velocity_jump": float(np.max(results["junction_jumps"][:, 1], initial=0.0)),
            "max_residual": float(np.nanmax(results["residuals"], initial=0.0)),
            "max_reach_error": float(np.max(results["reach_errors"])),
        }
        if "segment_planned" in results:  # runs stored before the planner was used lack it
            out["planned_segments"] = float(np.sum(results["segment_planned"]))
            out["planned_clearance"] = float(np.min(results["segment_clearance"]))
        # effort, rms_error, ok, min_clearance, ... of each run: the standard metrics
        # (`Procedure.full_summary`), in the rows `run_rows` names.
        goal = results["targets"][-1]
        for prefix, row in self.run_rows(cfg, results).items():
            run = B.sim_view(results, prefix)
            hand = frame_positions(robot, run["q"][-1:], frame)[0]
            out[f"{row}.final_hand_error"] = float(np.linalg.norm(hand - goal))
        return out

    def run_rows(self, cfg: ExperimentConfig, results: dict[str, np.ndarray]) -> dict[str, str]:
        """One row per plan and controller, named by the plan alone with one controller."""
        one = len(cfg.controllers) == 1
        return {
            f"{name}_{label}": name if one else f"{name}_{label}"
            for name in PLANS
            for label in cfg.controller_labels()
        }

    def plot(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray], out_dir: Path
    ) -> list[Path]:
        fig, axes = figure((12, 3.8), 1, 3)
        tg = results["targets"]
        for name, c in zip(PLANS, COLORS, strict=False):
            h = results[f"{name}__hand"]
            axes[0].plot(h[:, 0], h[:, 1], color=c, label=name)
            axes[1].plot(h[:, 0], h[:, 2], color=c, label=name)
            speed = np.linalg.norm(results[f"{name}__v"], axis=1)
            axes[2].plot(results[f"{name}__t"], speed, color=c, label=name)
        for ax, (i, j) in zip(axes[:2], ((0, 1), (0, 2)), strict=True):
            ax.plot(tg[:, i], tg[:, j], "k*", ms=10, label="goals")
            ax.set_xlabel("xyz"[i] + " [m]")
            ax.set_ylabel("xyz"[j] + " [m]")
            ax.set_aspect("equal", adjustable="datalim")
            ax.legend(fontsize=8)
        axes[0].set_title("hand path (top view)")
        axes[1].set_title("hand path (side view)")
        for tj in results["junction_times"]:
            axes[2].axvline(tj, color="0.6", ls="--", lw=0.8)
        axes[2].set_xlabel("t [s]")
        axes[2].set_ylabel(r"$\|\dot q\|$ [rad/s]")
        axes[2].set_title("joint speed (junctions dashed)")
        axes[2].legend(fontsize=8)
        paths = [save(fig, out_dir / "sequence.png")]
        fig, ax = figure((5, 3.5))
        e = [float(results[f"{n}__energy"]) for n in PLANS]
        ax.bar(list(PLANS), e, color=COLORS[:2])
        ax.set_ylabel("path energy at constant speed [J s]")
        ax.set_title(f"energy: geodesic {100 * (1 - e[0] / e[1]):.1f} % lower")
        paths.append(save(fig, out_dir / "energy.png"))
        return paths
