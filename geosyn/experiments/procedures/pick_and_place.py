"""Pick-and-place with a metric that changes with the load.

The hand reaches the object (``params.pick``) on the unloaded metric ``M(q)``, grasps it
(the scene's payload body, welded to the hand with mass 0, takes the object's mass:
`geosyn.sim.PayloadChange`), carries it over ``params.via`` (around the obstacle) to
``params.place`` and releases it. The joint configurations of the task are found once by
synergy reaching inside the joint limits (`task_sequence`: a goal missed by more than
``params.reach_tol`` fails, naming its segment); three plans join the same configurations:

- ``load_aware``: reach on ``M(q)``, carry on the load-shaped metric
  ``M(q) + J^T Lambda J`` (`LoadTerm`: the exact kinetic energy of the held object);
- ``unloaded``: every segment a geodesic of ``M(q)`` (the load ignored in planning);
- ``straight``: straight joint-space lines.

Among the scene's obstacles, a segment of the first two whose geodesic comes closer than
`segments.CLEARANCE` to an obstacle (on the robot file's own collision geometry) is the planner's
minimum-energy collision-free path on the same metric instead (`avoiding_sequence`); a
segment that cannot be joined fails, naming the segment, its start and goal and why. The
straight lines are the baseline as they are: their exact clearance is reported. A run
whose robot touches an obstacle in MuJoCo counts as failed, with the contact as reason
(`outcomes.contact_reason`).

All are tracked by computed torque whose model switches with the grasp: the robot's
dynamics until the grasp, the robot with the object lumped into the hand link after it,
and back at the release (`GraspSwitchedTorque`). Reported: the kinetic energy of each
plan in the true metric of each phase (``energy``: the paths at constant speed in their
own parameter, what a geodesic minimises; ``timed_energy``: with the rest-to-rest time
law, which weights the middle of each path more), the tracked effort, the tracking error, the
clearance to the obstacle, and the largest difference between the load metric and the
mass matrix of the robot with the object attached (Pinocchio). ``--video`` films the three
tracked runs with the pick, via and place points drawn; the object, a body of the scene
from the start (massless until the grasp), is drawn at the hand throughout.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import pinocchio as pin
from pydantic import Field

from geosyn.controllers import ComputedTorque, Controller, JointTrajectoryReference
from geosyn.core.types import Vector
from geosyn.experiments.procedures.base import Procedure, RunContext, check_required, register
from geosyn.experiments.procedures.common import EFFORT_LABEL, Duration, Steps
from geosyn.experiments.procedures.outcomes import contact_reason, fail_run
from geosyn.experiments.procedures.segments import (
    avoiding_sequence,
    exact_checker,
    held_clearance,
    path_clearance,
    task_sequence,
)
from geosyn.experiments.results.obstacle_view import draw_obstacles
from geosyn.experiments.results.plots import COLORS, figure, save, tracking_error_plot
from geosyn.experiments.results.run_video import MARKERS
from geosyn.experiments.run import build as B
from geosyn.experiments.run.scene import build_obstacles
from geosyn.experiments.schema import ExperimentConfig, PositiveFloat, Strict, Vec3
from geosyn.metrics import KineticEnergyMetric, Metric
from geosyn.metrics.planning import Planner
from geosyn.metrics.shaping import LoadTerm, ShapedMetric
from geosyn.robots import Robot
from geosyn.robots.kinematics import frame_positions
from geosyn.sim import PayloadChange
from geosyn.synergies.sequence import SynergySequence, straight_sequence
from geosyn.world import Payload

PLANS = ("load_aware", "unloaded", "straight")
#: The task's segments, named in messages.
SEGMENTS = ("start -> pick", "pick -> via", "via -> place")


class PickAndPlaceParams(Strict):
    """Parameters of `PickAndPlace`.

    Attributes:
        pick: (3,) hand position of the grasp [m].
        via: (3,) hand position the carry passes [m].
        place: (3,) hand position of the release [m].
        mass: mass of the object [kg].
        durations: (3,) times of the reach, the carry to via and to place [s].
        dwell: rest at the grasp and at the release [s].
        steps: RK4 steps of each geodesic (path samples - 1).
        sample_dt: sample period of the tracked reference [s].
        reach_tol: largest distance of the hand from a point it stops at [m].
        plan_budget: the planner's time budget per segment [s].
    """

    pick: Vec3
    via: Vec3
    place: Vec3
    mass: PositiveFloat = 1.5
    durations: Annotated[list[PositiveFloat], Field(min_length=3, max_length=3)] = [1.0, 1.0, 1.0]
    dwell: Duration = 0.2
    steps: Steps = 200
    sample_dt: Annotated[float, Field(gt=0.0, le=0.05)] = 0.005
    reach_tol: PositiveFloat = 1e-3
    plan_budget: Duration = 10.0


def attach_payload(robot: Robot, payload: Payload) -> Robot:
    """A copy of ``robot`` with ``payload`` lumped into the body of its frame's parent joint.

    The frame's placement moves the payload's spatial inertia into the joint frame; the
    mass matrix of the result is ``M(q) + J^T Lambda J`` (what `LoadTerm` adds).
    """
    model = pin.Model(robot.model)
    frame = model.frames[robot.frame_id(payload.frame)]
    body = pin.Inertia(payload.mass, np.array(payload.com), payload.rotational_inertia())
    jid = frame.parentJoint
    model.inertias[jid] = model.inertias[jid] + frame.placement.act(body)
    return dataclasses.replace(robot, model=model)


class GraspSwitchedTorque(Controller):
    """Computed torque whose dynamics model holds the object between grasp and release.

    Args:
        robot: the robot (model before the grasp and after the release; torque limits).
        loaded: the robot with the object attached (`attach_payload`).
        kp: position gain, scalar or (nv,) [1/s^2].
        kd: velocity gain, scalar or (nv,) [1/s].
        t_grasp: time of the grasp [s].
        t_release: time of the release [s].
    """

    def __init__(
        self,
        robot: Robot,
        loaded: Robot,
        kp: float | np.ndarray,
        kd: float | np.ndarray,
        t_grasp: float,
        t_release: float,
    ) -> None:
        super().__init__(robot)
        self.free = ComputedTorque(robot, kp, kd)
        self.holding = ComputedTorque(loaded, kp, kd)
        self.t_grasp, self.t_release = float(t_grasp), float(t_release)

    def _on_reference_changed(self) -> None:
        for c in (self.free, self.holding):
            c.set_reference(self._reference)  # type: ignore[arg-type]

    def _compute(self, t: float, q: Vector, v: Vector) -> Vector:
        inner = self.holding if self.t_grasp <= t < self.t_release else self.free
        self.diagnostics.extra["holding"] = float(inner is self.holding)
        return inner._compute(t, q, v)


def timed_reference(
    reach: SynergySequence, carry: SynergySequence, dt: float
) -> JointTrajectoryReference:
    """The reach, a dwell at rest, then the carry, sampled every ``dt`` [s] (C2 quintic)."""
    t1, q1, v1, a1 = reach.trajectory(dt)
    t2, q2, v2, a2 = carry.trajectory(dt)
    return JointTrajectoryReference(
        np.concatenate([t1, t2]),
        np.concatenate([q1, q2]),
        np.concatenate([v1, v2]),
        np.concatenate([a1, a2]),
    )


def split(seq: SynergySequence, t_carry: float) -> tuple[SynergySequence, SynergySequence]:
    """(the reach segment, the carry segments shifted to start at ``t_carry``)."""
    carry = [
        dataclasses.replace(s, t0=s.t0 - seq.segments[1].t0 + t_carry) for s in seq.segments[1:]
    ]
    return SynergySequence(seq.segments[:1]), SynergySequence(carry)


@register
class PickAndPlace(Procedure):
    """Reach on M(q), carry on the load metric around an obstacle; vs unloaded planning."""

    kind = "pick_and_place"
    #: The metric is the robot's kinetic energy (and the object's, while carried): a
    #: ``metric`` section would have no effect.
    sections = (
        "robot", "scene", "synergies", "controllers", "disturbances", "simulation", "outputs",
        "params",
    )  # fmt: skip
    description = (
        "pick-and-place: carry on the exact load metric vs the unloaded metric vs straight lines"
    )
    Params = PickAndPlaceParams
    units = {
        "energy": "J s",
        "energy_saving": "%",
        "load_metric_error": "kg m^2",
        "planned_clearance": "m",
    }

    @classmethod
    def check(cls, cfg: ExperimentConfig, params: Any, robot: Any) -> list[tuple[str, str]]:
        out = check_required(cfg, "synergies", "controllers")
        if not cfg.scene.payloads:
            out.append(("scene.payloads", "the object: one payload of mass 0 at the hand"))
        elif cfg.scene.payloads[0].mass != 0.0:
            out.append(("scene.payloads.0.mass", "must be 0 (the object is grasped later)"))
        if cfg.controllers and cfg.controllers[0].type != "computed_torque":
            out.append(("controllers.0.type", "computed_torque (its model switches)"))
        return out

    def run(self, ctx: RunContext) -> dict[str, np.ndarray]:
        cfg, robot, p = ctx.config, ctx.robot, ctx.params
        advance = ctx.progress(f"{cfg.name}: plans and runs", 2 + len(PLANS))
        free = KineticEnergyMetric(robot)
        syns = B.build_synergies(cfg, free, robot)
        frame = getattr(cfg.synergies, "frame", None) or robot.ee_frame
        empty = ctx.scene.payloads[0]
        obj = dataclasses.replace(empty, mass=p.mass)
        loaded_metric = ShapedMetric(free, [LoadTerm.from_payload(obj)])
        loaded_robot = attach_payload(robot, obj)
        points = np.array([p.pick, p.via, p.place])
        task = task_sequence(
            syns, points, frame, robot, p.durations, steps=p.steps, tol=p.reach_tol,
            names=SEGMENTS,
        )  # fmt: skip
        W = task.waypoints
        advance()
        metrics: dict[str, list[Metric]] = {
            "load_aware": [free, loaded_metric, loaded_metric],
            "unloaded": [free, free, free],
        }
        truth: list[Metric] = [free, loaded_metric, loaded_metric]
        obstacles = ctx.scene.obstacles
        planners: dict[tuple[int, int], Planner] = {}  # one per metric and held ball
        held: list[Payload | None] = [None, obj, obj]  # part of the robot while carried
        plans: dict[str, SynergySequence] = {}
        clearances: dict[str, list[float]] = {}
        planned: dict[str, list[float]] = {}
        for name, ms in metrics.items():
            plans[name], how = avoiding_sequence(
                ms, W, p.durations, obstacles, steps=p.steps, budget=p.plan_budget,
                seed=cfg.seed, names=SEGMENTS, planners=planners, held=held,
            )  # fmt: skip
            clearances[name] = [h.clearance for h in how]
            planned[name] = [float(h.planned) for h in how]
        plans["straight"] = straight_sequence(W, p.durations, steps=p.steps)
        exact = exact_checker(robot, obstacles)
        clearances["straight"] = [
            min(path_clearance(exact, s.q, obstacles), held_clearance(robot, b, s.q, obstacles))
            for s, b in zip(plans["straight"].segments, held, strict=True)
        ]
        planned["straight"] = [0.0] * (len(W) - 1)
        advance()
        t_carry = p.durations[0] + p.dwell
        t_grasp = p.durations[0] + 0.5 * p.dwell
        t_end = t_carry + p.durations[1] + p.durations[2]
        t_release = t_end + 0.5 * p.dwell
        q_check = W[1:]
        out: dict[str, np.ndarray] = {
            "points": points,
            MARKERS: points,  # pick, via and place, shown in the videos
            "waypoints": W,
            "reach_errors": np.array([s.reach_error for s in task.segments]),
            "times": np.array([t_grasp, t_carry, t_end, t_release]),
            "load_metric_error": np.array(
                max(
                    float(
                        np.max(np.abs(loaded_metric.G(q) - attached_mass_matrix(loaded_robot, q)))
                    )
                    for q in q_check
                )
            ),
        }
        gains = cfg.controllers[0].kwargs()  # computed torque (checked)
        for name, seq in plans.items():
            out[f"plan_{name}__energy"] = np.array(seq.path_energy(truth))
            out[f"plan_{name}__timed_energy"] = np.array(seq.energy(truth))
            out[f"plan_{name}__residual"] = np.array(
                max(
                    (s.geodesic_residual() for s in seq.segments if s.metric is not None),
                    default=0.0,
                )
            )
            out[f"plan_{name}__segment_clearance"] = np.array(clearances[name])
            out[f"plan_{name}__segment_planned"] = np.array(planned[name])
            reach, carry = split(seq, t_carry)
            ref = timed_reference(reach, carry, p.sample_dt)
            t, q, _, _ = carry.trajectory(p.sample_dt)
            out[f"plan_{name}__hand"] = frame_positions(
                robot, np.concatenate([reach.trajectory(p.sample_dt)[1], q]), frame
            )
            ctrl = GraspSwitchedTorque(
                robot, loaded_robot, gains["kp"], gains["kd"], t_grasp, t_release
            )
            dist = B.build_disturbances(cfg) + [
                PayloadChange(t_grasp, p.mass, 0),
                PayloadChange(t_release, 0.0, 0),
            ]
            res = B.simulate(
                cfg,
                robot,
                ctrl,
                ref,
                W[0],
                np.zeros(robot.nv),
                duration=t_release + p.dwell,
                disturbances=dist,
                scene=ctx.scene,
            )
            out |= B.sim_arrays(name, res)
            if (reason := contact_reason(B.sim_view(out, name))) is not None:
                planned_c = min(clearances[name])
                fail_run(out, name, f"{reason} (planned path's exact clearance {planned_c:.3g} m)")
            advance()
        return out

    def summarize(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray]
    ) -> dict[str, float]:
        # effort, rms_error, ok, min_clearance, ... of each plan's run: the standard
        # metrics (`Procedure.full_summary`).
        e = {n: float(results[f"plan_{n}__energy"]) for n in PLANS}
        out: dict[str, float] = {
            "load_metric_error": float(results["load_metric_error"]),
            "max_reach_error": float(np.max(results["reach_errors"])),
            "energy_saving_vs_unloaded": 100.0 * (1.0 - e["load_aware"] / e["unloaded"]),
            "energy_saving_vs_straight": 100.0 * (1.0 - e["load_aware"] / e["straight"]),
        }
        for n in PLANS:
            out[f"{n}.energy"] = e[n]
            out[f"{n}.timed_energy"] = float(results[f"plan_{n}__timed_energy"])
            out[f"{n}.residual"] = float(results[f"plan_{n}__residual"])
            clearance = results.get(f"plan_{n}__segment_clearance")
            if clearance is not None:  # runs stored before the planner was used lack it
                out[f"{n}.planned_clearance"] = float(np.min(clearance))
                out[f"{n}.planned_segments"] = float(np.sum(results[f"plan_{n}__segment_planned"]))
        return out

    def plot(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray], out_dir: Path
    ) -> list[Path]:
        fig, axes = figure((12, 3.8), 1, 3)
        pts = results["points"]
        for n, c in zip(PLANS, COLORS, strict=False):
            h = results[f"plan_{n}__hand"]
            axes[0].plot(h[:, 1], h[:, 2], color=c, label=n)
        axes[0].plot(pts[:, 1], pts[:, 2], "k*", ms=10, label="pick, via, place")
        hidden = draw_obstacles(axes[0], build_obstacles(cfg))  # scene file's too
        axes[0].set_xlabel("y [m]")
        axes[0].set_ylabel("z [m]")
        axes[0].set_aspect("equal", adjustable="datalim")
        axes[0].set_title("hand path (front view), obstacles grey"
                          + (f" ({hidden} half-space(s) across the view not drawn)"
                             if hidden else ""))  # fmt: skip
        axes[0].legend(fontsize=7)
        e = [float(results[f"plan_{n}__energy"]) for n in PLANS]
        axes[1].bar(list(PLANS), e, color=COLORS[:3])
        axes[1].set_ylabel("path energy, true metric [J s]")
        axes[1].set_title("planned energy (constant speed)")
        axes[1].set_ylim(0.9 * min(e), 1.02 * max(e))
        runs = {n: B.sim_view(results, n) for n in PLANS}
        eff = [B.effort(r["tau_applied"], cfg.simulation.control_dt) for r in runs.values()]
        axes[2].bar(list(PLANS), eff, color=COLORS[:3])
        axes[2].set_ylabel(EFFORT_LABEL)
        axes[2].set_title("tracked effort (gravity included)")
        tg, _, _, tr = results["times"]
        windows = [(tg, tg + 0.01, "grasp"), (tr, tr + 0.01, "release")]
        return [
            save(fig, out_dir / "pick_and_place.png"),
            tracking_error_plot(out_dir / "tracking_error.png", runs, None, windows),
        ]


def attached_mass_matrix(loaded: Robot, q: Vector) -> np.ndarray:
    """(n, n) mass matrix of the robot with the object attached (Pinocchio CRBA) [kg m^2]."""
    M = pin.crba(loaded.model, loaded.model.createData(), q)
    return np.triu(M) + np.triu(M, 1).T
