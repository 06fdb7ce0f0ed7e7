"""One robot description in every controller (issue 21): each property a robot file states
(viscous joint damping, dry joint friction, armature, a linear joint coupling, a free base
loaded with ``fixed_base=True``) reaches computed torque, the QP, the Riemannian PD and the
MPC (ddp and fatrop, torque control).

Referee: MuJoCo's own compile of the ORIGINAL file (``Simulation(plant="file")``; for the
free base with its free joint kept, stepped here directly). For each property and
controller: the controller built on the robot as loaded tracks a geodesic with an RMS
error within 2x of computed torque's, and the same controller built with the property
removed from its model (or, for the coupling, from the reference it is given) does
measurably worse, by the factor stated in `WORSE`. Both numbers are printed (``pytest -s``
shows the table; the figures are in benchmarks/RESULTS.md). The fixtures are one small
3-joint arm of this file, with one property each.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import NamedTuple

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from geosyn.controllers import (
    ComputedTorque,
    CoupledReference,
    GeodesicMPC,
    GeodesicReference,
    QPController,
    RiemannianPD,
)
from geosyn.controllers.base import Controller
from geosyn.metrics import CoupledMetric, KineticEnergyMetric
from geosyn.robots import RobotWarning, load_robot
from geosyn.robots.robot import Robot
from geosyn.sim import Simulation
from geosyn.synergies import GeodesicSynergy

#: The arm: 3 hinges under gravity, capsule links, 20 N m motors; one property per fixture.
ARM = """<mujoco model="property_arm">
  <compiler angle="radian"/>
  <option gravity="0 0 -9.81" timestep="0.001"/>
  <default>
    <joint armature="{armature}" damping="{damping}" frictionloss="{frictionloss}"
           range="-2.8 2.8"/>
    <geom type="capsule" size="0.03" contype="0" conaffinity="0"/>
  </default>
  <worldbody>
    <body name="base" pos="0.1 -0.2 0.5">
      {free}<geom type="box" size="0.08 0.08 0.04" mass="3"/>
      <body name="l1" pos="0 0 0.04">
        <joint name="j1" axis="0 0 1"/>
        <geom fromto="0 0 0 0 0 0.3" mass="2"/>
        <body name="l2" pos="0 0 0.3">
          <joint name="j2" axis="0 1 0"/>
          <geom fromto="0 0 0 0.3 0 0" mass="1.5"/>
          <body name="l3" pos="0.3 0 0">
            <joint name="j3" axis="0 1 0"/>
            <geom fromto="0 0 0 0.25 0 0" mass="1"/>
            <site name="tip" pos="0.25 0 0"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  {equality}
  <actuator>
    <motor joint="j1" ctrlrange="-20 20"/>
    <motor joint="j2" ctrlrange="-20 20"/>
    <motor joint="j3" ctrlrange="-20 20"/>
  </actuator>
</mujoco>
"""

#: Each property's fixture: what the file states beyond the bare arm.
PROPERTIES: dict[str, dict[str, str]] = {
    "damping": {"damping": "0.5"},
    "frictionloss": {"frictionloss": "0.3"},
    "armature": {"armature": "0.05"},
    "coupling": {
        "equality": '<equality><joint joint1="j3" joint2="j2" polycoef="0.1 0.5 0 0 0"/></equality>'
    },
    "fixed_base": {"free": '<freejoint name="root"/>'},
}

#: How much worse (RMS ratio) each controller must do with the property removed.
WORSE = {"damping": 10.0, "frictionloss": 10.0, "armature": 5.0, "coupling": 10.0}
WORSE_UNWELDED = 10.0  # the free base left free in the plant (see `_unwelded_rms`)

Q0 = np.array([0.3, -0.4, 0.6])  # start [rad]
V0 = np.array([0.8, -0.6, 0.9])  # initial geodesic velocity [rad/s]
Z0, ZDOT0 = Q0[:2], V0[:2]  # the coupled arm's independent joints j1, j2
DURATION = 1.0  # tracked [s]
# The reference lasts longer than the run by more than an MPC horizon (10 x 0.02 s): a
# geodesic reference steps to rest at its end, which a horizon would see coming.
REFERENCE_DURATION = DURATION + 0.3
CONTROL_DT = 1e-3  # [s], the file's timestep


class Case(NamedTuple):
    """One property's fixture.

    Attributes:
        path: the MJCF file (the plant).
        robot: the robot as loaded from it (the controllers' full model).
        without: the controllers' model with the property removed, or None when that is
            not meaningful for a joint-space controller (then ``why`` says why and
            the property is removed from the plant instead).
        ref: the reference tracked by the full model; ref_without: by ``without``.
        why: why ``without`` is None.
    """

    path: Path
    robot: Robot
    without: Robot | None
    ref: GeodesicReference | CoupledReference
    ref_without: GeodesicReference | CoupledReference
    why: str = ""


def _load(path: Path, **options: object) -> Robot:
    with warnings.catch_warnings():  # no velocity limits in the file; the coupling note
        warnings.simplefilter("ignore", RobotWarning)
        return load_robot(str(path), **options)


def _geodesic(robot: Robot, q0: np.ndarray, v0: np.ndarray) -> GeodesicReference:
    synergy = GeodesicSynergy(KineticEnergyMetric(robot), q0, v0)
    return GeodesicReference(synergy, duration=REFERENCE_DURATION)


def _case(directory: Path, name: str) -> Case:
    spec = {"armature": "0", "damping": "0", "frictionloss": "0", "free": "", "equality": ""}
    spec.update(PROPERTIES[name])
    path = directory / f"{name}.xml"
    path.write_text(ARM.format(**spec))
    robot = _load(path, fixed_base=True) if name == "fixed_base" else _load(path)
    if name == "coupling":
        c = robot.coupling
        assert c is not None and c.independent == ("j1", "j2")
        metric = CoupledMetric(KineticEnergyMetric(robot), c)
        inner = GeodesicReference(GeodesicSynergy(metric, Z0, ZDOT0), duration=REFERENCE_DURATION)
        # Coupling ignored: the geodesic of the joints' metric from the same lifted state.
        without = dataclasses.replace(robot, coupling=None)
        ref_without = _geodesic(without, c.S @ Z0 + c.c, c.S @ ZDOT0)
        return Case(path, robot, without, CoupledReference(inner, c), ref_without)
    ref = _geodesic(robot, Q0, V0)
    if name == "damping":
        return Case(path, robot, dataclasses.replace(robot, damping=np.zeros(3)), ref, ref)
    if name == "frictionloss":
        return Case(path, robot, dataclasses.replace(robot, frictionloss=np.zeros(3)), ref, ref)
    if name == "armature":
        model = robot.model.copy()
        model.armature[:] = 0.0
        return Case(path, robot, dataclasses.replace(robot, model=model), ref, ref)
    why = (
        "a joint-space controller of the unwelded (floating) model commands 6 base"
        " coordinates the welded arm does not have; the property is removed from the plant"
        " instead (the file's free joint kept)"
    )
    return Case(path, robot, None, ref, ref, why)


@pytest.fixture(scope="module")
def cases(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Case]:
    directory = tmp_path_factory.mktemp("property_matrix")
    return {name: _case(directory, name) for name in PROPERTIES}


def _ct(robot: Robot) -> ComputedTorque:
    return ComputedTorque(robot, 400.0, 40.0)


def _mpc(solver: str) -> Callable[[Robot], GeodesicMPC]:
    def make(robot: Robot) -> GeodesicMPC:
        metric = KineticEnergyMetric(robot)
        return GeodesicMPC(robot, metric, horizon=10, dt=0.02, control="torque", solver=solver)

    return make


CONTROLLERS: dict[str, Callable[[Robot], Controller]] = {
    "computed_torque": _ct,
    "qp": lambda r: QPController(r, 400.0, 40.0, CONTROL_DT),
    "riemannian_pd": lambda r: RiemannianPD(r, 20.0, 5.0),
    "mpc_ddp": _mpc("ddp"),
    "mpc_fatrop": _mpc("fatrop"),
}
SLOW = {"mpc_ddp", "mpc_fatrop"}  # compiled OCPs: seconds per robot on a cold cache


def _rms(case: Case, controller: Controller, ref: GeodesicReference | CoupledReference) -> float:
    """RMS joint error [rad] inside MuJoCo's compile of the original file."""
    if case.without is None:  # the plant welds the file's free joint, and says so
        with pytest.warns(RuntimeWarning, match="welded"):
            sim = Simulation(case.robot, controller, plant="file", control_dt=CONTROL_DT)
    else:
        sim = Simulation(case.robot, controller, plant="file", control_dt=CONTROL_DT)
    result = sim.run(ref.sample(0.0).q, ref.sample(0.0).v, DURATION, ref)
    assert result.ok, result.diverged
    return float(np.sqrt(np.mean((result.q - result.q_ref) ** 2)))


def _unwelded_rms(case: Case, controller: Controller) -> float:
    """RMS joint error [rad] in MuJoCo's compile of the original floating file with its
    free joint kept (the base not welded): the controller's torques on the arm's joints,
    clipped to the limits, as in the file plant; the base starts at rest at the file's
    pose."""
    m = mujoco.MjModel.from_xml_path(str(case.path))
    m.opt.timestep = CONTROL_DT
    m.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    d = mujoco.MjData(m)
    joints = [m.joint(name) for name in case.robot.joint_names]
    qa = np.array([int(m.jnt_qposadr[j.id]) for j in joints])
    da = np.array([int(m.jnt_dofadr[j.id]) for j in joints])
    ref, tau_max = case.ref, case.robot.tau_max
    q0, v0 = ref.sample(0.0).q, ref.sample(0.0).v
    d.qpos[qa], d.qvel[da] = q0, v0
    controller.set_reference(ref)
    controller.reset(q0, v0, 0.0)
    n = int(round(DURATION / CONTROL_DT))
    err = np.empty((n, qa.size))
    for k in range(n):
        t = k * CONTROL_DT
        q, v = d.qpos[qa].copy(), d.qvel[da].copy()
        err[k] = q - ref.sample(t).q
        tau = controller.compute(t, q, v)
        d.qfrc_applied[da] = np.clip(tau, -tau_max, tau_max)
        mujoco.mj_step(m, d)
    return float(np.sqrt(np.mean(err**2)))


@pytest.fixture(scope="module")
def table() -> Iterator[dict[tuple[str, str], tuple[float, float, float]]]:
    """``(property, controller) -> (RMS with, RMS without, computed torque's RMS)``,
    printed as a table at the end of the module."""
    rows: dict[tuple[str, str], tuple[float, float, float]] = {}
    yield rows
    print("\nproperty      controller        RMS [rad]   removed [rad]  ratio  vs CT")
    for (prop, ctl), (with_, without, ct) in sorted(rows.items()):
        print(
            f"{prop:13s} {ctl:16s} {with_:10.2e}  {without:12.2e} {without / with_:6.0f}"
            f" {with_ / ct:6.2f}"
        )


@pytest.fixture(scope="module")
def ct_rms(cases: dict[str, Case]) -> dict[str, float]:
    """Computed torque's RMS [rad] per property (the bound's reference)."""
    return {name: _rms(case, _ct(case.robot), case.ref) for name, case in cases.items()}


_PAIRS = [
    pytest.param(p, c, id=f"{p}-{c}", marks=[pytest.mark.slow] if c in SLOW else [])
    for p in PROPERTIES
    for c in CONTROLLERS
]


@pytest.mark.parametrize(("prop", "controller"), _PAIRS)
def test_property_reaches_the_controller(
    cases: dict[str, Case],
    ct_rms: dict[str, float],
    table: dict[tuple[str, str], tuple[float, float, float]],
    prop: str,
    controller: str,
) -> None:
    case, make = cases[prop], CONTROLLERS[controller]
    with_ = _rms(case, make(case.robot), case.ref)
    if case.without is None:  # fixed base: see Case.why
        without = _unwelded_rms(case, make(case.robot))
        factor = WORSE_UNWELDED
    else:
        without = _rms(case, make(case.without), case.ref_without)
        factor = WORSE[prop]
    table[(prop, controller)] = (with_, without, ct_rms[prop])
    print(f"{prop} {controller}: {with_:.3e} rad with, {without:.3e} without ({case.why})")
    assert with_ <= 2.0 * ct_rms[prop], (with_, ct_rms[prop])
    assert without >= factor * with_, (with_, without)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("solver", "control"), [("ddp", "torque"), ("fatrop", "torque"), ("fatrop", "acceleration")]
)
def test_mpc_commanded_torque_with_friction_keeps_the_limits(cases, solver, control) -> None:
    """The dry-friction feed-forward is part of the commanded torque the limits bound: j2's
    reference needs -5.94 N m for the rigid body plus -0.3 N m friction, and its limit
    is 6.15 N m (between the two). The plan's commanded torque (its torque plus the
    friction) reaches the limit and stays within it; the torque the solver bounds is net
    of the friction (bounding it alone would command up to 6.45 N m)."""
    case = cases["frictionloss"]
    tau_max = np.array([20.0, 6.15, 20.0])
    robot = dataclasses.replace(case.robot, tau_max=tau_max)
    metric = KineticEnergyMetric(robot)
    mpc = GeodesicMPC(robot, metric, horizon=10, dt=0.02, control=control, solver=solver)
    assert "modelled" in mpc.diagnostics.notes["frictionloss"]
    mpc.set_reference(case.ref)
    plan = mpc.solve(0.0, Q0, V0)
    assert plan.success, plan.status
    assert plan.friction is not None
    v_ref = np.array([case.ref.sample(k * 0.02).v for k in range(10)])  # stage starts
    np.testing.assert_allclose(plan.friction, 0.3 * np.tanh(v_ref / 0.01), rtol=0, atol=1e-12)
    if control == "torque":  # the controls are the torques net of the friction
        net = plan.u
    else:  # the controls are accelerations: the torque is the inverse dynamics (Pinocchio)
        data = robot.model.createData()
        x, u = plan.x, plan.u
        net = np.array([pin.rnea(robot.model, data, x[k, :3], x[k, 3:], u[k]) for k in range(10)])
    np.testing.assert_allclose(plan.tau, net + plan.friction, rtol=0, atol=1e-9)
    assert np.all(np.abs(plan.tau) <= tau_max + 1e-6), np.abs(plan.tau).max(axis=0)
    assert np.max(np.abs(plan.tau[:, 1])) > 6.15 - 1e-3  # the limit is active
    assert np.max(np.abs(net[:, 1])) < 6.15 - 0.29  # what the solver bounds is net of it


@pytest.mark.slow
@pytest.mark.parametrize(
    ("solver", "control", "effort"),
    [
        ("ipopt", "torque", "torque"),
        ("ddp", "torque", "metric"),
        ("fatrop", "acceleration", "acceleration"),
    ],
)
def test_every_mpc_family_models_dry_friction(cases, ct_rms, solver, control, effort) -> None:
    """The other solver families and efforts carry the friction feed-forward too (same
    bound and factor as the matrix above)."""
    case = cases["frictionloss"]

    def make(robot: Robot) -> GeodesicMPC:
        metric = KineticEnergyMetric(robot)
        return GeodesicMPC(
            robot, metric, horizon=10, dt=0.02, control=control, solver=solver, effort=effort
        )

    with_ = _rms(case, make(case.robot), case.ref)
    without = _rms(case, make(case.without), case.ref)
    print(f"frictionloss mpc {solver}/{control}/{effort}: {with_:.3e} with, {without:.3e} without")
    assert with_ <= 2.0 * ct_rms["frictionloss"], (with_, ct_rms["frictionloss"])
    assert without >= WORSE["frictionloss"] * with_, (with_, without)
