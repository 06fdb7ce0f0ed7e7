"""The box-DDP solver family: compiled Riccati steps and rollouts of the torque-level
tracking OCP, behind `geosyn.controllers.mpc.backend.TrackingBackend`."""

from geosyn.controllers.mpc.ddp.options import DDPOptions
from geosyn.controllers.mpc.ddp.tracking import DDPTracking, ddp_backend

__all__ = ["DDPOptions", "DDPTracking", "ddp_backend"]
