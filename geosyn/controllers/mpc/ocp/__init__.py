"""The description of the tracking OCP, shared by every solver family: settings, stage
dynamics (with the RK4 step's Jacobians and the compiled curvature-free form), cost terms
with their Gauss-Newton derivatives, soft penalties, obstacle slots of world shapes, and
the plan record every backend returns. Nothing here imports a solver family."""

from geosyn.controllers.mpc.ocp.obstacles import ObstacleSlots
from geosyn.controllers.mpc.ocp.plan import MPCPlan, ReferenceSamples
from geosyn.controllers.mpc.ocp.settings import OCPSettings

__all__ = ["MPCPlan", "ObstacleSlots", "OCPSettings", "ReferenceSamples"]
