"""The scene of a run, built once from its config: robot, obstacles, payloads, contact,
cameras.

`build_run_scene` turns the config's ``robot`` and ``scene`` sections into `geosyn.world`
objects once per run (the runner calls it); the same `BuiltScene` is handed to the metric
builder (obstacle and load terms), the controllers (an MPC's clearance), the simulation
and the videos, so no consumer rebuilds its own slice from the YAML. `build_obstacles`
and `build_payloads` are the only places a config obstacle or payload becomes a shape
(`build_obstacles` also reads ``scene.mjcf``, a MuJoCo scene file's static geoms).
"""

from __future__ import annotations

import functools
import os
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from geosyn.experiments import schema as S
from geosyn.robots import Robot, load_robot
from geosyn.sim import CameraView
from geosyn.world import (
    Box,
    Capsule,
    HalfSpace,
    MjcfObstacles,
    Payload,
    Shape,
    Sphere,
    load_mjcf_obstacles,
    rotation_from_rpy,
)

OBSTACLES: dict[str, Callable[[Any], Shape]] = {
    "sphere": lambda o: Sphere(tuple(o.center), o.radius),
    "box": lambda o: Box(
        tuple(o.center), tuple(o.half_extents), tuple(map(tuple, rotation_from_rpy(o.rpy)))
    ),
    "capsule": lambda o: Capsule(tuple(o.p0), tuple(o.p1), o.radius),
    "halfspace": lambda o: HalfSpace(tuple(o.normal), o.offset),
}
"""Registry of obstacle builders by config ``type``: section -> `geosyn.world` shape."""


def build_robot(cfg: S.ExperimentConfig) -> Robot:
    """The robot of the config (``load_robot(name, **options)``)."""
    return load_robot(cfg.robot.name, **cfg.robot.options.model_dump(exclude_none=True))


def mjcf_obstacles(cfg: S.ExperimentConfig) -> MjcfObstacles | None:
    """The static geoms of the config's MuJoCo scene file (``scene.mjcf``), or None.

    A file is compiled once per version (its path, size and modification time): the
    config's checks and the run read it several times.

    Raises:
        geosyn.world.InvalidGeometry: MuJoCo cannot load the file.
    """
    m = cfg.scene.mjcf
    if m is None:
        return None
    try:
        st = os.stat(m.file)
        stamp = (st.st_mtime_ns, st.st_size)
    except OSError:  # not a file: MuJoCo's own error names it
        return load_mjcf_obstacles(m.file, visual=m.visual)
    return _read_mjcf(m.file, m.visual, stamp)


@functools.lru_cache(maxsize=16)
def _read_mjcf(file: str, visual: bool, stamp: tuple[int, int]) -> MjcfObstacles:
    """`load_mjcf_obstacles` of one version (``stamp``) of a file (its shapes are frozen)."""
    return load_mjcf_obstacles(file, visual=visual)


def build_obstacles(cfg: S.ExperimentConfig, file: MjcfObstacles | None = None) -> list[Shape]:
    """Obstacles of the scene as `geosyn.world` shapes: ``scene.obstacles`` in order, then
    the MuJoCo scene file's (``file``, read from ``scene.mjcf`` when None)."""
    file = mjcf_obstacles(cfg) if file is None else file
    return [OBSTACLES[o.type](o) for o in cfg.scene.obstacles] + list(file.shapes if file else ())


def obstacle_field(cfg: S.ExperimentConfig, index: int, file: MjcfObstacles | None) -> str:
    """The config field of obstacle ``index`` of `build_obstacles`: ``scene.obstacles.<i>``,
    or ``scene.mjcf`` and the file's geom name."""
    n = len(cfg.scene.obstacles)
    if index < n or file is None:
        return f"scene.obstacles.{index}"
    return f"scene.mjcf (geom {file.names[index - n]!r})"


def build_payloads(cfg: S.ExperimentConfig, robot: Robot) -> list[Payload]:
    """Payloads of the scene as `geosyn.world.Payload` (frame defaults to the robot's end
    effector)."""
    return [
        Payload(**(p.kwargs() | {"frame": p.frame or robot.ee_frame})) for p in cfg.scene.payloads
    ]


@dataclass(frozen=True)
class BuiltScene:
    """The world of one run, built once (`build_run_scene`) and shared by its consumers.

    Attributes:
        robot: the robot (``robot`` section).
        obstacles: the obstacles as `geosyn.world` shapes (``scene.obstacles``), in order.
        payloads: the payloads welded to the robot (``scene.payloads``), in order.
        contact: the obstacles collide with the robot in MuJoCo (``scene.contact``).
        plant: ``"model"`` (geosyn's rebuilt model) or ``"file"`` (the robot's own MJCF).
        cameras: fixed RGB-D cameras of the scene (none unless a procedure places them,
            e.g. ``perception_reach`` from its ``params.cameras``).
    """

    robot: Robot
    obstacles: tuple[Shape, ...] = ()
    payloads: tuple[Payload, ...] = ()
    contact: bool = False
    plant: str = "model"
    cameras: tuple[CameraView, ...] = ()


def build_run_scene(cfg: S.ExperimentConfig, robot: Robot | None = None) -> BuiltScene:
    """The `BuiltScene` of a config (``robot``: an already loaded robot of the config).

    Cost: loads the robot (when not given) and builds the shapes; no MuJoCo model.
    """
    robot = build_robot(cfg) if robot is None else robot
    file, m = mjcf_obstacles(cfg), cfg.scene.mjcf
    if file is not None and m is not None and (file.approximated or file.skipped):
        warnings.warn(  # said, never dropped silently
            f"scene.mjcf: {m.file}: {len(file.shapes)} obstacle(s) read"
            + (f"; enclosed: {'; '.join(file.approximated)}" if file.approximated else "")
            + (f"; left out: {'; '.join(file.skipped)}" if file.skipped else ""),
            UserWarning,
            stacklevel=2,
        )
    return BuiltScene(
        robot=robot,
        obstacles=tuple(build_obstacles(cfg, file)),
        payloads=tuple(build_payloads(cfg, robot)),
        contact=cfg.scene.contact,
        plant=cfg.robot.plant,
    )


__all__ = [
    "OBSTACLES",
    "BuiltScene",
    "build_obstacles",
    "build_payloads",
    "build_robot",
    "build_run_scene",
    "mjcf_obstacles",
    "obstacle_field",
]
