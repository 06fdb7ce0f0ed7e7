"""Videos of a run directory's motions, for every experiment kind.

`run_motions` finds what a run moved: every closed-loop run stored by
`geosyn.experiments.run.build.sim_arrays` (``{prefix}__t``, ``{prefix}__q``, ``{prefix}__q_ref``),
or, for a kind that simulates nothing, every stored path (``{name}__t`` with
``{name}__q`` of the robot's size: geodesics, transported synergies, ...). `write_videos`
renders one video per motion (`geosyn.sim.Clip`: the controller's name, time stamps, the
end effector's reference and actual paths, arrows for pushes and wrenches, payloads and
obstacles) and never raises: the run is kept, and what failed is returned, for the
runner to record in ``run.json`` and the run log.

A run simulated on the robot's original MJCF file (``robot: {plant: file}``) is drawn
from that file. A procedure can add balls to its videos: ``video_markers`` (M, 3) [m],
fixed points shown in every video of the run (goals, pick and place points, in
`MARKER_RGBA`), and ``{name}__target_position`` (T, 3) [m], a target that moves with the
motion ``name`` (sampled at its ``{name}__t``; radius ``{name}__target_radius`` [m],
default `TARGET_RADIUS`; in `TARGET_RGBA`).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from geosyn.experiments.run.build import build_disturbances
from geosyn.experiments.run.floating import floating_videos
from geosyn.experiments.run.scene import BuiltScene, build_run_scene
from geosyn.experiments.schema import ExperimentConfig
from geosyn.robots import Robot
from geosyn.sim import Clip, Motion
from geosyn.sim.render_scene import Marker

#: Results key of the fixed points drawn in every video of a run, (M, 3) [m].
MARKERS = "video_markers"
#: Radius [m] and colour of those points; radius and colour of a moving target.
MARKER_RADIUS, MARKER_RGBA = 0.015, (0.95, 0.6, 0.05, 0.9)
TARGET_RADIUS, TARGET_RGBA = 0.02, (0.1, 0.85, 0.1, 1.0)


class RunMotion(NamedTuple):
    """One motion stored in a run's results.

    Attributes:
        name: the prefix of its arrays (the controller's label, or ``{path}_{label}``).
        t: (T,) time stamps [s].
        q: (T, nq) joint positions [rad].
        q_ref: (T, nq) reference positions [rad] (NaN: none), or None.
        simulated: a closed-loop run (disturbances act on it), not a computed path.
        target: (T, 3) position of a target moving with it [m], or None.
        target_radius: the target's radius [m].
    """

    name: str
    t: np.ndarray
    q: np.ndarray
    q_ref: np.ndarray | None
    simulated: bool
    target: np.ndarray | None = None
    target_radius: float = TARGET_RADIUS


def run_motions(results: dict[str, np.ndarray], nq: int) -> list[RunMotion]:
    """The motions of a run's results, in storage order.

    Closed-loop runs when there are any (their references are shown in them), else every
    stored path ``{name}__t`` / ``{name}__q`` with (T,) and (T, nq) arrays.

    Args:
        results: the arrays of ``results.npz``.
        nq: the robot's number of joint positions.

    Returns:
        The motions (empty when the kind stores none, e.g. ``pga_vs_pca``).
    """
    sims: list[RunMotion] = []
    paths: list[RunMotion] = []
    for key, q in results.items():
        if not key.endswith("__q"):
            continue
        name = key[: -len("__q")]
        t = results.get(f"{name}__t")
        q = np.asarray(q)
        if t is None or np.ndim(t) != 1 or q.shape != (len(t), nq) or len(t) < 2:
            continue
        t = np.asarray(t, dtype=np.float64)
        if np.any(np.diff(t) <= 0.0):
            continue
        q_ref = results.get(f"{name}__q_ref")
        simulated = f"{name}__tau_applied" in results
        target = results.get(f"{name}__target_position")
        if target is not None and np.shape(target) != (len(t), 3):
            target = None
        radius = float(results.get(f"{name}__target_radius", TARGET_RADIUS))
        motion = RunMotion(
            name,
            t,
            q,
            None if q_ref is None else np.asarray(q_ref),
            simulated,
            None if target is None else np.asarray(target, dtype=np.float64),
            radius,
        )
        (sims if simulated else paths).append(motion)
    return sims or paths


def _markers(motion: RunMotion, fixed: np.ndarray | None) -> list[Any]:
    """The balls of a motion's video: the run's fixed points, the motion's moving target."""
    out = []
    if fixed is not None:
        for point in np.asarray(fixed, dtype=np.float64).reshape(-1, 3):
            out.append(Marker(np.zeros(1), point[None, :], MARKER_RADIUS, MARKER_RGBA))
    if motion.target is not None:
        out.append(Marker(motion.t, motion.target, motion.target_radius, TARGET_RGBA))
    return out


def motion_clip(
    cfg: ExperimentConfig, scene: BuiltScene, motion: RunMotion, fixed: np.ndarray | None = None
) -> Any:
    """The `geosyn.sim.Clip` of one motion in the run's scene (``fixed``: (K, 3) marker
    points [m]); ``outputs`` sets its size, frame rate and trail."""
    o = cfg.outputs
    # A stored run's ticks end one control period before the run: film up to its end.
    end = motion.t[-1] + cfg.simulation.control_dt if motion.simulated else None
    return Clip(
        Motion(motion.t, motion.q, motion.q_ref, end),
        scene.robot,
        o.fps,
        min(o.width, 1280),
        min(o.height, 960),
        payloads=scene.payloads,
        obstacles=scene.obstacles,
        trail=o.trail,
        disturbances=build_disturbances(cfg) if motion.simulated else (),
        label=motion.name,
        plant=scene.plant,
        markers=_markers(motion, fixed),
    )


def _floating_videos(
    cfg: ExperimentConfig,
    robot: Robot,
    results: dict[str, np.ndarray],
    out_dir: Path,
    record: dict[str, Any],
) -> dict[str, Any]:
    """`write_videos` of a floating-base robot (`geosyn.experiments.run.floating`)."""
    t0 = time.perf_counter()
    try:
        record["files"] = floating_videos(cfg, robot, results, out_dir)
    except Exception as err:  # a failed video never throws the finished run away
        record["error"] = f"video of a floating-base robot: {type(err).__name__}: {err}"
        return record
    frames = sum(  # one per 1/fps over each run (`geosyn.sim.floating_video`)
        len(np.arange(t[0], t[-1] + 1e-12, 1.0 / cfg.outputs.fps))
        for t in (results[f"{label}__t"] for label in cfg.controller_labels())
    )
    record["frames"] = frames
    record["seconds_per_frame"] = (time.perf_counter() - t0) / max(frames, 1)
    record["robot_drawn_as"] = "geosyn's twin (capsules between joints) on the floor"
    return record


def write_videos(
    cfg: ExperimentConfig,
    robot: Robot,
    results: dict[str, np.ndarray],
    out_dir: Path,
    *,
    scene: BuiltScene | None = None,
) -> dict[str, Any]:
    """Render ``video_{name}.{gif|mp4}`` for every motion of a run; never raises.

    Args:
        cfg: the run's config (``outputs`` sets format, fps, size and trail).
        robot: the robot of the run.
        results: the run's arrays.
        out_dir: where the videos go.
        scene: the run's world (`geosyn.experiments.run.scene`); built from the config
            when not given.

    Returns:
        ``{"files": [names written], "frames": F, "seconds_per_frame": s, "error": None or
        "what failed: why", "robot_drawn_as": "its own meshes", "collision capsules
        (why)" or "the simulated plant: its original file ..."}``; a kind that stores no
        motion gets an error saying so.
    """
    record: dict[str, Any] = {"files": [], "frames": 0, "seconds_per_frame": None, "error": None}
    if robot.floating:  # standing on the floor with its base free: its own scene
        return _floating_videos(cfg, robot, results, out_dir, record)
    motions = run_motions(results, robot.nq)
    if not motions:
        record["error"] = (
            f"kind {cfg.kind!r} stores no motion of the robot (no '<name>__t' and"
            f" '<name>__q' arrays with {robot.nq} joints), so there is nothing to film"
        )
        return record
    scene = build_run_scene(cfg, robot) if scene is None else scene
    t0 = time.perf_counter()
    clip = None
    for motion in motions:
        path = out_dir / f"video_{motion.name}.{cfg.outputs.video_format}"
        try:
            clip = motion_clip(cfg, scene, motion, results.get(MARKERS))
            clip.save(path)
        except Exception as err:  # a failed video never throws the finished run away
            path.unlink(missing_ok=True)
            record["error"] = f"video of {motion.name!r}: {type(err).__name__}: {err}"
            break
        record["files"].append(path.name)
        record["frames"] += len(clip.indices(clip.motion()))
    if record["frames"]:
        record["seconds_per_frame"] = (time.perf_counter() - t0) / record["frames"]
    if clip is not None:
        try:
            record["robot_drawn_as"] = clip.drawn_as()
        except Exception as err:  # recorded, never raised (see above)
            record["robot_drawn_as"] = f"unknown: {type(err).__name__}: {err}"
    return record


__all__ = ["MARKERS", "RunMotion", "motion_clip", "run_motions", "write_videos"]
