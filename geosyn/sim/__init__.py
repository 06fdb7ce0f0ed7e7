"""Closed-loop simulation in MuJoCo: scenes with payloads and obstacles, disturbances, logs,
videos.

`Simulation(robot, controller, ...)` runs torque control of a `Robot` in a MuJoCo model built
from the same description (`build_scene`: payload bodies welded to links, obstacle geoms),
under `Disturbance`s (`Push`, `Wrench`, `PayloadChange`, `TorqueNoise`, `SensorNoise`,
`Latency`), and returns a per-tick `SimResult` (saved to .npz; a long run's log is
written to disk in chunks as it runs and mapped back read-only, so memory stays bounded:
`geosyn.sim.log_spool`, `spool_directory`). A `Clip` draws a result
headless (EGL unless ``MUJOCO_GL`` names another backend) to frames, a .gif (Pillow) or an
.mp4 (imageio + ffmpeg); `render_video` is its one-call form. Importing this package sets
nothing global: the OpenGL context is made when a video is drawn.
"""

if not __name__.startswith("geosyn."):  # the folder imported as a top-level package
    raise ImportError(f"import geosyn.sim, not {__name__}: one module, one name")


from geosyn.sim.camera import CameraView
from geosyn.sim.camera_sensor import CameraSensor, Frames, render_rgbd
from geosyn.sim.disturbances import (
    Disturbance,
    Latency,
    PayloadChange,
    Push,
    SensorNoise,
    TorqueNoise,
    Wrench,
)
from geosyn.sim.errors import RenderError, SimError, SpoolError, UnknownBody
from geosyn.sim.log import SimResult
from geosyn.sim.log_spool import spool_directory
from geosyn.sim.perception import PinholeCamera, TargetEstimate, estimate_ball
from geosyn.sim.render import Clip, Motion, render_video
from geosyn.sim.scene import Scene, build_scene
from geosyn.sim.simulation import Simulation

__all__ = [
    "CameraSensor",
    "CameraView",
    "Clip",
    "Disturbance",
    "Frames",
    "Latency",
    "Motion",
    "PayloadChange",
    "PinholeCamera",
    "Push",
    "RenderError",
    "Scene",
    "SensorNoise",
    "SimError",
    "SimResult",
    "Simulation",
    "SpoolError",
    "TargetEstimate",
    "TorqueNoise",
    "UnknownBody",
    "Wrench",
    "build_scene",
    "estimate_ball",
    "render_rgbd",
    "render_video",
    "spool_directory",
]
