"""Controllers: ``compute(t, q, v) -> tau`` behind one interface, no simulator inside.

Computed torque, a passivity-based Riemannian PD, an inverse-dynamics QP with limits, a
geodesic-tracking MPC, geodesic references and replanning, a whole-body QP for
floating-base robots standing on their feet, and a Pinocchio plant for simulator-free
tests.
"""

if not __name__.startswith("geosyn."):  # the folder imported as a top-level package
    raise ImportError(f"import geosyn.controllers, not {__name__}: one module, one name")


from geosyn.controllers.base import Controller, ControllerDiagnostics
from geosyn.controllers.computed_torque import ComputedTorque
from geosyn.controllers.coupled_reference import CoupledReference
from geosyn.controllers.errors import ControllerError, NoReference, SolverFailed
from geosyn.controllers.mpc import GeodesicMPC, MPCPlan, OpenLoopSolution
from geosyn.controllers.plant import PinocchioPlant, Rollout
from geosyn.controllers.qp import QPController
from geosyn.controllers.reference import (
    GeodesicReference,
    JointTrajectoryReference,
    Reference,
    ReferenceSample,
)
from geosyn.controllers.replan import replan_geodesic
from geosyn.controllers.riemannian_pd import RiemannianPD
from geosyn.controllers.sequence_reference import SequenceReference
from geosyn.controllers.whole_body import WholeBodyController
from geosyn.controllers.whole_body_reference import StanceSynergyReference

__all__ = [
    "ComputedTorque",
    "Controller",
    "ControllerDiagnostics",
    "ControllerError",
    "CoupledReference",
    "GeodesicMPC",
    "MPCPlan",
    "OpenLoopSolution",
    "GeodesicReference",
    "JointTrajectoryReference",
    "NoReference",
    "PinocchioPlant",
    "QPController",
    "Reference",
    "ReferenceSample",
    "RiemannianPD",
    "SequenceReference",
    "Rollout",
    "SolverFailed",
    "StanceSynergyReference",
    "WholeBodyController",
    "replan_geodesic",
]
