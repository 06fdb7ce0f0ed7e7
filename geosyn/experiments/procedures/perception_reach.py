"""Perception in the loop: a camera sees a moving ball, synergy weights reach it.

Once per robot and synergy set, a `SynergyMap` (target position -> weights) is fitted on
seeded synergy combinations. Then, for each of ``n_targets`` seeded targets (each the
hand's end position of a random combination, so reachable), a green ball starts
``drift`` away from its final position and moves there at constant speed during the
first ``move_time`` seconds. Fixed RGB-D cameras, taking turns, render the scene at
``rate`` Hz in all (`CameraSensor`; two views, so that the arm hides the ball from at most
one of them); at each new image the controller estimates the ball's centre
(`estimate_ball`), maps it to weights (refined by Gauss-Newton when the map misses by
more than ``bound``), integrates the combined geodesic from the start and tracks it
(computed torque, rest-to-rest time law over ``duration``).

Each target is a run (`outcomes`): it fails when the simulation does not complete, when
the hand ends farther than ``success_radius`` from the true final target, or when the
reference it tracked leaves the joint limits, each with its reason in
``target_<i>__status``; every summary counts them alike (``target_<i>.ok``,
``failed_runs``). Reported: success rate, the perception-to-torque latency (image in hand
to torque out, rendering excluded), the perception error, the map's error before
refinement and the error and time of `reach` alone on the same targets (NaN, counted in
``reach_outside_limits``, where no motion inside the joint limits reaches a target).
``--video`` films the first target's run (``target_0``) with the ball where the
simulation put it at each tick (``target_0__target_position``).
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field

from geosyn.controllers import ComputedTorque, Controller, GeodesicReference
from geosyn.controllers import JointTrajectoryReference as Hold
from geosyn.core.types import Vector
from geosyn.experiments.procedures.base import Procedure, RunContext, check_required, register
from geosyn.experiments.procedures.common import Duration
from geosyn.experiments.procedures.outcomes import fail_run, run_status, status_oks
from geosyn.experiments.procedures.perception_targets import (
    ROWS,
    map_vs_reach,
    target_failures,
    target_paths,
)
from geosyn.experiments.results.plots import COLORS, figure, save
from geosyn.experiments.run import build as B
from geosyn.experiments.schema import ExperimentConfig, PositiveFloat, Strict, Vec3
from geosyn.metrics import Metric
from geosyn.robots import Robot
from geosyn.robots.kinematics import frame_position
from geosyn.sim import CameraView, Simulation
from geosyn.sim.camera_sensor import CameraSensor, Frames
from geosyn.sim.perception import estimate_ball
from geosyn.synergies.perception_map import SynergyMap
from geosyn.world import Sphere

GREEN = (0.1, 0.85, 0.1, 1.0)


class CameraParams(Strict):
    """A fixed camera (`geosyn.sim.CameraView`).

    Attributes:
        lookat: (3,) point the camera looks at [m].
        distance: distance of the camera from that point [m].
        azimuth: azimuth of the view [deg].
        elevation: elevation of the view [deg] (negative: from above).
    """

    lookat: Vec3 = [0.45, 0.0, 0.45]
    distance: PositiveFloat = 1.4
    azimuth: float = 180.0
    elevation: float = -30.0

    def view(self) -> CameraView:
        """This camera as a `CameraView`."""
        return CameraView(tuple(self.lookat), self.distance, self.azimuth, self.elevation)  # type: ignore[arg-type]


class PerceptionReachParams(Strict):
    """Parameters of `PerceptionReach`.

    Attributes:
        n_targets: seeded targets, each a run.
        weight_scale: std of the synergy weights the map is fitted on [-].
        target_scale: targets come from weights of std ``target_scale * weight_scale`` [-].
        fit_samples: synergy combinations the map is fitted on.
        degree: polynomial degree of the map.
        steps: RK4 steps of each geodesic.
        duration: time of the reaching motion [s].
        settle: simulated time after the motion [s].
        rate: images per second, all cameras together [Hz].
        drift: distance the ball moves to its final position [m].
        move_time: time the ball takes to get there [s].
        radius: radius of the ball [m].
        bound: the map's weights are refined when the hand would miss by more [m].
        success_radius: a run whose hand ends farther from the target fails [m].
        width: image width [px].
        height: image height [px].
        cameras: the fixed cameras, taking turns.
    """

    n_targets: Annotated[int, Field(ge=1, le=1000)] = 50
    weight_scale: PositiveFloat = 0.5
    target_scale: Annotated[float, Field(gt=0.0, le=1.0)] = 0.8
    fit_samples: Annotated[int, Field(ge=20, le=20_000)] = 400
    degree: Annotated[int, Field(ge=1, le=4)] = 3
    steps: Annotated[int, Field(ge=10, le=1000)] = 50
    duration: Duration = 1.0
    settle: Duration = 0.4
    rate: PositiveFloat = 10.0
    drift: Annotated[float, Field(ge=0.0)] = 0.03
    move_time: Duration = 0.4
    radius: PositiveFloat = 0.03
    bound: PositiveFloat = 3e-3
    success_radius: PositiveFloat = 0.01
    width: Annotated[int, Field(ge=16, le=1280)] = 320
    height: Annotated[int, Field(ge=16, le=960)] = 240
    cameras: Annotated[list[CameraParams], Field(min_length=1)] = [
        CameraParams(),
        CameraParams(azimuth=135.0, elevation=-45.0, distance=1.5),
    ]


class PerceptionController(Controller):
    """Computed torque on a geodesic re-planned from each new camera image.

    Args:
        robot: the robot.
        metric: the metric of the synergies.
        smap: the fitted synergy map.
        frames: the camera's mailbox.
        p: the procedure's parameters.
        kp: position gain [1/s^2].
        kd: velocity gain [1/s].
    """

    def __init__(
        self,
        robot: Robot,
        metric: Metric,
        smap: SynergyMap,
        frames: Frames,
        p: PerceptionReachParams,
        kp: Any,
        kd: Any,
    ) -> None:
        super().__init__(robot)
        self.metric, self.smap, self.frames, self.p = metric, smap, frames, p
        self.inner = ComputedTorque(robot, kp, kd)
        self.reset(smap.q_start, np.zeros(robot.nv))

    def reset(self, q: Vector, v: Vector, t: float = 0.0) -> None:
        super().reset(q, v, t)
        hold = Hold(np.array([0.0, 1.0]), np.array([self.smap.q_start] * 2))
        self.set_reference(hold)
        self.inner.set_reference(hold)
        self._seen = -1.0
        self._prior: tuple[Vector, Vector] | None = None
        #: (time [s], estimate (3,) [m], true position (3,) [m], map error [m], refined)
        self.log: list[tuple[float, Vector, Vector, float, bool]] = []
        self.latencies: list[float] = []
        self.misses = 0

    def _compute(self, t: float, q: Vector, v: Vector) -> Vector:
        latest = self.frames.latest
        if latest is None or latest[0] == self._seen:
            return self.inner._compute(t, q, v)
        c0 = time.perf_counter()
        t_img, rgb, depth, cam = latest
        self._seen = t_img
        p = self.p
        est = estimate_ball(cam, rgb, depth, GREEN[:3], p.radius)
        if est is None:  # not seen (occluded): keep the current plan
            self.misses += 1
            return self.inner._compute(t, q, v)
        sol = self.smap.solve(est.position, bound=p.bound, prior=self._prior)
        self._prior = (est.position, sol.weights)
        ref = GeodesicReference(
            sol.trajectory,
            self.metric,
            time_scale=p.duration / self.smap.duration,
            rest_to_rest=True,
        )
        self.inner.set_reference(ref)
        self.set_reference(ref)
        tau = self.inner._compute(t, q, v)
        self.latencies.append(time.perf_counter() - c0)
        truth = self.frames.true_positions[-1][1]
        self.log.append((t_img, est.position, truth, sol.map_error, sol.refined))
        return tau


@register
class PerceptionReach(Procedure):
    """Camera-driven reaching with a fitted synergy map, the target moving."""

    kind = "perception_reach"
    #: The scene is the ball and the cameras of ``params``: a ``scene`` section would have
    #: no effect.
    sections = (
        "robot", "metric", "synergies", "controllers", "disturbances", "simulation", "outputs",
        "params",
    )  # fmt: skip
    description = "RGB-D camera -> ball position -> synergy weights -> geodesic, re-planned online"
    Params = PerceptionReachParams
    units = {
        "success_rate": "%",
        "latency_median": "ms",
        "latency_p95": "ms",
        "render_median": "ms",
        "perception_error_median": "mm",
        "perception_error_max": "mm",
        "map_error_median": "mm",
        "map_error_max": "mm",
        "final_error": "mm",
        "final_error_median": "mm",
        "final_error_max": "mm",
        "reach_error_median": "mm",
        "reach_time_median": "ms",
        "map_time_median": "ms",
    }

    @classmethod
    def check(cls, cfg: ExperimentConfig, params: Any, robot: Any) -> list[tuple[str, str]]:
        out = check_required(cfg, "synergies", "controllers")
        if cfg.controllers and cfg.controllers[0].type != "computed_torque":
            out.append(("controllers.0.type", "computed_torque"))
        if cfg.robot.plant != "model":
            out.append(
                ("robot.plant", "must be 'model': the cameras render geosyn's model of the scene")
            )
        return out

    def run(self, ctx: RunContext) -> dict[str, np.ndarray]:
        cfg, robot, p = ctx.config, ctx.robot, ctx.params
        metric = B.build_metric(cfg, robot, scene=ctx.scene)
        syns = B.build_synergies(cfg, metric, robot)
        frame = getattr(cfg.synergies, "frame", None) or robot.ee_frame
        smap = SynergyMap(syns, frame, robot, duration=1.0, steps=p.steps, degree=p.degree)
        smap.fit(p.fit_samples, p.weight_scale, seed=cfg.seed)
        finals, drifts = target_paths(smap, p, cfg.seed)
        frames = Frames()
        scene = dataclasses.replace(ctx.scene, cameras=tuple(c.view() for c in p.cameras))
        sensor = CameraSensor(frames, 0, GREEN, list(scene.cameras), p.rate, p.width, p.height)
        gains = cfg.controllers[0].kwargs()  # computed torque (checked)
        ctrl = PerceptionController(robot, metric, smap, frames, p, gains["kp"], gains["kd"])
        sim = Simulation(
            robot,
            ctrl,
            obstacles=[Sphere(tuple(finals[0]), p.radius)],
            disturbances=[sensor, *B.build_disturbances(cfg)],
            seed=cfg.seed,
            **cfg.simulation.kwargs(),
        )
        advance = ctx.progress(f"{cfg.name}: targets", p.n_targets)
        fid = robot.frame_id(frame)
        rows: dict[str, list[Any]] = {k: [] for k in ROWS}
        lat: list[float] = []
        renders: list[float] = []
        out: dict[str, np.ndarray] = {"finals": finals, "drifts": drifts}
        try:
            for i, (pf, d) in enumerate(zip(finals, drifts, strict=True)):

                def path(
                    t: float, pf: np.ndarray = pf, d: np.ndarray = d, move: float = p.move_time
                ) -> np.ndarray:
                    return pf - d * max(0.0, 1.0 - t / move)

                frames.path = path
                res = sim.run(smap.q_start, None, p.duration + p.settle)
                hand = frame_position(robot, res.q_final, fid)
                log = ctrl.log
                est_err = [float(np.linalg.norm(e - tr)) for _, e, tr, _, _ in log]
                rows["final_error"].append(float(np.linalg.norm(hand - pf)))
                rows["perception_error"].append(max(est_err, default=np.nan))
                rows["replans"].append(len(log))
                rows["refined"].append(sum(r for *_, r in log))
                rows["misses"].append(ctrl.misses)
                lat += ctrl.latencies
                renders += frames.render_times
                run = f"target_{i}"
                if i == 0:  # the ball is the scene's only "obstacle": no clearance kept
                    arrays = B.sim_arrays(run, res)
                    out |= {k: v for k, v in arrays.items() if not k.endswith("__clearance")}
                    # the ball where the simulation put it at each tick (drawn in the video)
                    out[f"{run}__target_position"] = np.array([path(t) for t in res.t])
                    out[f"{run}__target_radius"] = np.array(p.radius)
                    out["example_log_t"] = np.array([r[0] for r in log])
                    out["example_estimates"] = np.array([r[1] for r in log])
                    out["example_truth"] = np.array([r[2] for r in log])
                else:
                    out[f"{run}__status"] = np.array(res.status)
                for reason in target_failures(robot, res.q_ref, rows["final_error"][-1], p):
                    fail_run(out, run, reason)
                rows["ok"].append(float(run_status(out, run) == "ok"))
                advance()
        finally:
            sensor_copy = sim.disturbances[0]
            if isinstance(sensor_copy, CameraSensor):
                sensor_copy.close()
        out |= {f"target__{k}": np.array(v, dtype=np.float64) for k, v in rows.items()}
        out["latencies"], out["render_times"] = np.array(lat), np.array(renders)
        out |= map_vs_reach(smap, syns, finals, frame, robot, p)
        return out

    def summarize(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray]
    ) -> dict[str, float]:
        fe = results["target__final_error"]
        mm = 1e3
        lat = results["latencies"] * mm
        return {
            "targets": float(len(fe)),
            "success_rate": 100.0 * float(np.mean(fe <= params.success_radius)),
            "final_error_median": float(np.median(fe)) * mm,
            "final_error_max": float(np.max(fe)) * mm,
            "latency_median": float(np.median(lat)) if lat.size else float("nan"),
            "latency_p95": float(np.percentile(lat, 95)) if lat.size else float("nan"),
            "render_median": float(np.median(results["render_times"])) * mm,
            "perception_error_median": float(np.nanmedian(results["target__perception_error"]))
            * mm,
            "perception_error_max": float(np.nanmax(results["target__perception_error"])) * mm,
            "map_error_median": float(np.median(results["map_error"])) * mm,
            "map_error_max": float(np.max(results["map_error"])) * mm,
            "refined_fraction": float(
                np.sum(results["target__refined"]) / max(np.sum(results["target__replans"]), 1)
            ),
            "misses": float(np.sum(results["target__misses"])),
            "reach_error_median": float(np.nanmedian(results["reach_error"])) * mm,
            "reach_time_median": float(np.median(results["reach_time"])) * mm,
            "map_time_median": float(np.median(results["map_time"])) * mm,
            "ok_runs": float(np.sum(results["target__ok"])),
            "reach_outside_limits": float(np.sum(np.isnan(results["reach_error"]))),
        } | self.target_rows(results)

    @staticmethod
    def target_rows(results: dict[str, np.ndarray]) -> dict[str, float]:
        """``target_<i>.ok`` (from the run's status, `outcomes`) and ``.final_error`` [mm]
        of every target whose status is stored (runs stored before per-target statuses
        have none)."""
        fe = results["target__final_error"]
        out: dict[str, float] = {}
        for i in range(len(fe)):
            run = f"target_{i}"
            if f"{run}__status" in results:
                out |= status_oks(results, {run: run})
                out[f"{run}.final_error"] = float(fe[i]) * 1e3
        return out

    def plot(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray], out_dir: Path
    ) -> list[Path]:
        fig, axes = figure((13, 3.8), 1, 3)
        t, est, tru = (
            results["example_log_t"],
            results["example_estimates"],
            results["example_truth"],
        )
        for k, c in zip(range(3), COLORS, strict=False):
            axes[0].plot(t, tru[:, k], color=c, label=f"true {'xyz'[k]}")
            axes[0].plot(t, est[:, k], "o", color=c, ms=3, label=f"camera {'xyz'[k]}")
        axes[0].set_xlabel("t [s]")
        axes[0].set_ylabel("target position [m]")
        axes[0].set_title("moving target, estimates at each image")
        axes[0].legend(fontsize=6, ncol=2)
        fe = results["target__final_error"] * 1e3
        axes[1].hist(fe, bins=20, color=COLORS[0])
        axes[1].axvline(params.success_radius * 1e3, color="k", ls="--", label="success radius")
        axes[1].set_xlabel("final hand error [mm]")
        axes[1].set_title(
            f"{len(fe)} targets: {100 * np.mean(fe <= params.success_radius * 1e3):.0f} % success"
        )
        axes[1].legend(fontsize=8)
        axes[2].hist(results["latencies"] * 1e3, bins=30, color=COLORS[1])
        axes[2].set_xlabel("perception-to-torque latency [ms]")
        axes[2].set_title("latency (rendering excluded)")
        paths = [save(fig, out_dir / "perception_reach.png")]
        fig, ax = figure((5, 3.5))
        vals = [
            np.median(results["map_error"]),
            np.max(results["map_error"]),
            np.nanmedian(results["reach_error"]),
        ]
        ax.bar(["map median", "map max", "reach median"], np.array(vals) * 1e3, color=COLORS[:3])
        ax.set_ylabel("hand error [mm]")
        ax.set_yscale("log")
        ax.set_title(
            f"map {np.median(results['map_time']) * 1e3:.2f} ms vs reach {np.median(results['reach_time']) * 1e3:.0f} ms"
        )
        paths.append(save(fig, out_dir / "map_vs_reach.png"))
        return paths
