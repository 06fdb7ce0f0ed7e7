"""Config sections of the controllers; each stands for its `geosyn.controllers` class and
takes its defaults from that class's constructor.

The robot, the metric and the reference come from the experiment, and the QP's period
``dt`` is ``simulation.control_dt``. Feedback gains that a constructor requires have the
config defaults given to `python_defaults` here (and nowhere else).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from geosyn.controllers import ComputedTorque, GeodesicMPC, QPController, RiemannianPD
from geosyn.controllers.mpc import (
    MAX_HORIZON,
    MAX_SOLVER_ITER,
    MAX_STAGE_DT,
    MIN_SOLVER_TOL,
    MIN_STAGE_DT,
    DDPOptions,
    NLPOptions,
)
from geosyn.controllers.qp import MAX_ITER as QP_MAX_ITER
from geosyn.controllers.whole_body import WholeBodyController
from geosyn.experiments.schema.section import Section, python_defaults
from geosyn.experiments.schema.values import Gain, NonNegFloat, PositiveFloat

Label = Annotated[str, Field(pattern=r"^[A-Za-z0-9_\-]+$")]

_COMPUTED_TORQUE = python_defaults(ComputedTorque, kp=400.0, kd=40.0)
_RIEMANNIAN_PD = python_defaults(RiemannianPD, lam=20.0, k=50.0)
_QP = python_defaults(QPController, kp=400.0, kd=40.0)
_MPC = python_defaults(GeodesicMPC)
_NLP = python_defaults(NLPOptions)
_DDP = python_defaults(DDPOptions)
_WHOLE_BODY = python_defaults(WholeBodyController)


class _ControllerBase(Section):
    """A controller section; ``label`` names its runs (default: its type, numbered)."""

    label: Label | None = None


class ComputedTorqueConfig(_ControllerBase):
    """`ComputedTorque`: gains ``kp`` [1/s^2] and ``kd`` [1/s]; joint-friction
    compensation (default: on when the robot has damping or friction)."""

    builds = (ComputedTorque,)
    type: Literal["computed_torque"]
    kp: Gain = _COMPUTED_TORQUE["kp"]
    kd: Gain = _COMPUTED_TORQUE["kd"]
    compensate_friction: bool | None = _COMPUTED_TORQUE["compensate_friction"]
    friction_velocity: PositiveFloat = _COMPUTED_TORQUE["friction_velocity"]


class RiemannianPDConfig(_ControllerBase):
    """`RiemannianPD`: gains ``lam`` [1/s] and ``k`` [N m s/rad]; the dry-friction
    feed-forward's smoothing velocity ``friction_velocity`` [rad/s]."""

    builds = (RiemannianPD,)
    type: Literal["riemannian_pd"]
    lam: Gain = _RIEMANNIAN_PD["lam"]
    k: Gain = _RIEMANNIAN_PD["k"]
    friction_velocity: PositiveFloat = _RIEMANNIAN_PD["friction_velocity"]


class QPConfig(_ControllerBase):
    """`QPController` (period ``simulation.control_dt``): gains ``kp`` [1/s^2], ``kd``
    [1/s], solver tolerances and iterations, braking settings [s], [rad/s^2]."""

    builds = (QPController,)
    type: Literal["qp"]
    kp: Gain = _QP["kp"]
    kd: Gain = _QP["kd"]
    eps: PositiveFloat = _QP["eps"]
    eps_abs: PositiveFloat = _QP["eps_abs"]
    position_horizon: PositiveFloat | None = _QP["position_horizon"]
    braking_acceleration: PositiveFloat | None = _QP["braking_acceleration"]
    max_iter: Annotated[int, Field(ge=1, le=QP_MAX_ITER)] = _QP["max_iter"]
    max_inner_iter: Annotated[int, Field(ge=1, le=QP_MAX_ITER)] = _QP["max_inner_iter"]
    compensate_friction: bool | None = _QP["compensate_friction"]
    friction_velocity: PositiveFloat = _QP["friction_velocity"]


class NLPSolverConfig(Section):
    """`NLPOptions` of the MPC's ``solver`` (``type: fatrop`` or ``ipopt``): tolerance,
    iterations, barrier parameters, ``plugin_options`` passed to the plugin as they are."""

    builds = (NLPOptions,)
    parameter_names = {"type": "solver"}
    type: Literal["fatrop", "ipopt"]
    tol: Annotated[float, Field(ge=MIN_SOLVER_TOL, le=1.0)] = _NLP["tol"]
    max_iter: Annotated[int, Field(ge=1, le=MAX_SOLVER_ITER)] = _NLP["max_iter"]
    mu_init: PositiveFloat = _NLP["mu_init"]
    mu_warm: PositiveFloat = _NLP["mu_warm"]
    plugin_options: dict[str, bool | int | float | str] | None = _NLP["plugin_options"]

    def build(self) -> NLPOptions:
        """The options object."""
        return NLPOptions(**self.kwargs())


class DDPSolverConfig(Section):
    """`DDPOptions` of the MPC's ``solver`` (``type: ddp``; torque control and effort):
    cold-solve tolerance and iterations, warm iterations, soft-limit and clearance
    weights, control regularisation, backward pass (native C or CasADi's graph)."""

    builds = (DDPOptions,)
    type: Literal["ddp"]
    tol: Annotated[float, Field(ge=MIN_SOLVER_TOL, le=1.0)] = _DDP["tol"]
    max_iter: Annotated[int, Field(ge=1, le=MAX_SOLVER_ITER)] = _DDP["max_iter"]
    warm_iterations: Annotated[int, Field(ge=1, le=MAX_SOLVER_ITER)] = _DDP["warm_iterations"]
    limit_weight: PositiveFloat = _DDP["limit_weight"]
    regularisation: PositiveFloat = _DDP["regularisation"]
    clearance_weight: PositiveFloat = _DDP["clearance_weight"]
    backward: Literal["native", "casadi"] = _DDP["backward"]

    def build(self) -> DDPOptions:
        """The options object."""
        return DDPOptions(**self.kwargs())


SolverConfig = Annotated[NLPSolverConfig | DDPSolverConfig, Field(discriminator="type")]


def _solver_options(value: object) -> object:
    return value.build() if isinstance(value, NLPSolverConfig | DDPSolverConfig) else value


class MPCConfig(_ControllerBase):
    """`GeodesicMPC`. ``effort``/``tau_weight`` None: chosen from ``control`` by the
    controller; ``solver``: ``fatrop``, ``ipopt`` or ``ddp`` (their default options), or
    a section of the family's options, e.g. ``{type: ddp, warm_iterations: 2}`` or
    ``{type: ipopt, max_iter: 100, plugin_options: {...}}`` (`NLPSolverConfig`,
    `DDPSolverConfig`); ``clearance_margin`` [m] (``solver: ddp``) keeps the scene's
    obstacles away from the robot's collision spheres (``clearance_spheres: file``: from
    spheres covering its file's collision geometry, more of them). ``solver`` null (default): ``ddp`` with ``control: torque`` (the
    fastest torque-level solver) wherever the DDP solves the problem, ``fatrop``
    otherwise (acceleration control, ``hessian: exact``). ``joint_limit_guard`` (default
    true): every torque passes the joint-limit guard, which keeps joint positions and
    velocities inside their limits in closed loop (hard, whatever the solver; the DDP's
    own limits are penalties) and the torque inside its limits; false: the torque is
    only clamped. Each tick the guard changed is counted in the diagnostics."""

    builds = (GeodesicMPC,)
    to_python = {"solver": _solver_options}
    type: Literal["mpc"]
    horizon: Annotated[int, Field(ge=1, le=MAX_HORIZON)] = _MPC["horizon"]
    dt: Annotated[float, Field(ge=MIN_STAGE_DT, le=MAX_STAGE_DT)] = _MPC["dt"]
    solver: Literal["fatrop", "ipopt", "ddp"] | SolverConfig | None = _MPC["solver"]
    q_weight: NonNegFloat = _MPC["q_weight"]
    v_weight: NonNegFloat = _MPC["v_weight"]
    tau_weight: NonNegFloat | None = _MPC["tau_weight"]
    terminal_weight: NonNegFloat = _MPC["terminal_weight"]
    effort: Literal["torque", "metric", "acceleration"] | None = _MPC["effort"]
    control: Literal["torque", "acceleration"] = _MPC["control"]
    rk4_steps: Literal[1, 2] = _MPC["rk4_steps"]
    hessian: Literal["gauss-newton", "exact"] = _MPC["hessian"]
    kp: Gain = _MPC["kp"]
    kd: Gain = _MPC["kd"]
    plan_tolerance: NonNegFloat = _MPC["plan_tolerance"]
    max_solve_time: PositiveFloat = _MPC["max_solve_time"]
    clearance_margin: PositiveFloat | None = _MPC["clearance_margin"]
    clearance_spheres: Literal["file"] | None = _MPC["clearance_spheres"]
    tracking: Literal["euclidean", "metric"] = _MPC["tracking"]
    joint_limit_guard: bool = _MPC["joint_limit_guard"]


class WholeBodyConfig(_ControllerBase):
    """`WholeBodyController` (floating-base robots on a ``stance``): the QP over
    accelerations and contact forces (proxsuite), gains ``kp`` [1/s^2], ``kd`` [1/s],
    task ``weights``, ``contact_gain`` [1/s]; contacts, friction cone and ``f_min`` are
    the ``stance`` section's."""

    builds = (WholeBodyController,)
    type: Literal["whole_body"]
    kp: Gain = _WHOLE_BODY["kp"]
    kd: Gain = _WHOLE_BODY["kd"]
    weights: Gain = _WHOLE_BODY["weights"]
    contact_gain: NonNegFloat = _WHOLE_BODY["contact_gain"]
    force_regularisation: PositiveFloat = _WHOLE_BODY["force_regularisation"]
    compensate_friction: bool = _WHOLE_BODY["compensate_friction"]
    friction_velocity: PositiveFloat = _WHOLE_BODY["friction_velocity"]


ControllerConfig = Annotated[
    ComputedTorqueConfig | RiemannianPDConfig | QPConfig | MPCConfig | WholeBodyConfig,
    Field(discriminator="type"),
]

__all__ = [
    "WholeBodyConfig",
    "ComputedTorqueConfig",
    "ControllerConfig",
    "DDPSolverConfig",
    "MPCConfig",
    "NLPSolverConfig",
    "QPConfig",
    "RiemannianPDConfig",
    "SolverConfig",
]
