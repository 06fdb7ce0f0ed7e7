"""Closed-loop simulation in MuJoCo: scenes with payloads and obstacles, disturbances, logs,
videos.

`Simulation(robot, controller, ...)` runs torque control of a `Robot` in a MuJoCo model built
from the same description (`build_scene`: payload bodies welded to links, obstacle geoms),
under `Disturbance`s (`Push`, `Wrench`, `PayloadChange`, `TorqueNoise`, `SensorNoise`,
`Latency`), and returns a per-tick `SimResult` (saved to .npz). `render_video` draws a
result headless (EGL) to .gif (Pillow) or .mp4 (imageio + ffmpeg).
"""

if not __name__.startswith("geosyn."):  # the folder imported as a top-level package
    raise ImportError(f"import geosyn.sim, not {__name__}: one module, one name")


# render first: it sets MUJOCO_GL=egl (headless) before anything imports mujoco.
from geosyn.sim.render import (  # isort: skip
    CameraView,
    iter_frames,
    render_frames,
    render_video,
    write_frames,
)
from geosyn.sim.disturbances import (
    Disturbance,
    Latency,
    PayloadChange,
    Push,
    SensorNoise,
    TorqueNoise,
    Wrench,
)
from geosyn.sim.errors import RenderError, SimError, UnknownBody, UnsupportedObstacle
from geosyn.sim.log import SimResult
from geosyn.sim.scene import Clearance, ObstacleGeom, Payload, Scene, build_scene, link_placement
from geosyn.sim.simulation import SPEED_FACTOR, ControllerLike, ReferenceLike, Simulation

__all__ = [
    "SPEED_FACTOR",
    "CameraView",
    "Clearance",
    "ControllerLike",
    "Disturbance",
    "Latency",
    "ObstacleGeom",
    "Payload",
    "PayloadChange",
    "Push",
    "ReferenceLike",
    "RenderError",
    "Scene",
    "SensorNoise",
    "SimError",
    "SimResult",
    "Simulation",
    "TorqueNoise",
    "UnknownBody",
    "UnsupportedObstacle",
    "Wrench",
    "build_scene",
    "iter_frames",
    "link_placement",
    "render_frames",
    "render_video",
    "write_frames",
]
