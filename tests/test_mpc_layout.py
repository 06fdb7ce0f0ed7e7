"""The MPC's rooms keep their plan ("describe, then solve"): neither solver family imports
the other, the shared description imports no family, the MPC never imports the metric
shaping terms, every module is on the package map, the YAML ``solver:`` sections take
their defaults from the options classes, and both families read each cost's one
definition (its derivatives equal automatic differentiation of its expression)."""

from __future__ import annotations

import ast
import dataclasses
import inspect
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from conftest import get_metric, get_robot
from geosyn.controllers import mpc
from geosyn.controllers.mpc.backend import TrackingBackend
from geosyn.controllers.mpc.ddp.options import DDPOptions
from geosyn.controllers.mpc.ddp.tracking import DDPTracking
from geosyn.controllers.mpc.nlp.options import NLPOptions
from geosyn.controllers.mpc.nlp.tracking import NLPTracking
from geosyn.controllers.mpc.ocp.costs import (
    EFFORT_TERMS,
    StageSymbols,
    StateTracking,
    TerminalStateTracking,
)
from geosyn.controllers.mpc.ocp.obstacles import ObstacleSlots
from geosyn.controllers.mpc.ocp.penalties import ClearancePenalty, StateLimitPenalty
from geosyn.core.errors import InvalidArgument
from geosyn.world import Box, Sphere

ROOT = Path(__file__).resolve().parents[1]
MPC = ROOT / "geosyn" / "controllers" / "mpc"


def _imports(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            out += [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            out += [a.name for a in node.names]
    return out


def _offenders(folder: str, forbidden: tuple[str, ...]) -> list[str]:
    return [
        f"{path.relative_to(ROOT)} imports {mod}"
        for path in sorted((MPC / folder).rglob("*.py"))
        for mod in _imports(path)
        if mod.startswith(forbidden)
    ]


@pytest.mark.parametrize(
    ("folder", "other"), [("nlp", "ddp"), ("ddp", "nlp"), ("ocp", "nlp"), ("ocp", "ddp")]
)
def test_a_room_never_imports_another_family(folder: str, other: str) -> None:
    offenders = _offenders(folder, (f"geosyn.controllers.mpc.{other}",))
    assert not offenders, offenders


def test_the_contract_and_the_description_import_no_family() -> None:
    for mod in _imports(MPC / "backend.py"):
        assert not mod.startswith(("geosyn.controllers.mpc.nlp", "geosyn.controllers.mpc.ddp"))


def test_the_mpc_never_imports_metric_shaping() -> None:
    offenders = _offenders(".", ("geosyn.metrics.shaping",))
    assert not offenders, offenders


def test_the_package_map_lists_every_module() -> None:
    doc = mpc.__doc__ or ""
    modules = sorted(
        p.relative_to(MPC).with_suffix("").as_posix().replace("/", ".")
        for p in MPC.rglob("*.py")
        if p.name != "__init__.py"
    )
    missing = [m for m in modules if f"`.{m}`" not in doc]
    assert not missing, f"mpc/__init__.py's package map does not list {missing}"


def test_each_family_implements_the_backend_protocol() -> None:
    assert {"hessian", "notes"} <= set(TrackingBackend.__annotations__)
    assert {"solve", "forget"} <= set(dir(TrackingBackend))
    for cls in (NLPTracking, DDPTracking):
        assert {"solve", "forget"} <= set(vars(cls)), cls
        assert (
            inspect.signature(cls.solve).parameters.keys()
            == inspect.signature(TrackingBackend.solve).parameters.keys()
        )


@pytest.mark.parametrize("options", [NLPOptions, DDPOptions])
def test_yaml_solver_sections_take_their_defaults_from_the_options_classes(options) -> None:
    from geosyn.experiments.schema.controllers import DDPSolverConfig, NLPSolverConfig

    section = NLPSolverConfig if options is NLPOptions else DDPSolverConfig
    kind = "ipopt" if options is NLPOptions else "ddp"
    built = section.model_validate({"type": kind}).build()
    default = options("ipopt") if options is NLPOptions else options()
    assert built == default
    fields = {section.parameter_names.get(n, n) for n in section.model_fields}
    assert {f.name for f in dataclasses.fields(options)} <= fields


def test_solver_shorthands_mean_the_default_options() -> None:
    robot, metric = get_robot("planar2"), get_metric("planar2")
    for name, want in (("ipopt", NLPOptions("ipopt")), ("ddp", DDPOptions())):
        ctl = mpc.GeodesicMPC(robot, metric, horizon=3, control="torque", solver=name)
        assert ctl.solver_options == want
        assert isinstance(ctl._tracker, TrackingBackend)  # its members, at run time
    with pytest.raises(InvalidArgument, match="solver"):
        mpc.GeodesicMPC(robot, metric, horizon=3, solver={"tol": 1.0})  # type: ignore[arg-type]


def _symbols(n: int) -> StageSymbols:
    x, u = ca.SX.sym("x", 2 * n), ca.SX.sym("u", n)
    return StageSymbols(x, u, u, ca.SX.sym("qr", n), ca.SX.sym("vr", n), ca.SX.sym("tr", n),
                        ca.SX(0, 1))  # fmt: skip


def _terms(robot, metric, n: int):
    rng = np.random.default_rng(4)
    w = rng.uniform(0.5, 2.0, n)
    slots = ObstacleSlots(robot, [Sphere((0.6, 0.2, 0.0), 0.15), Box((0.2, 0.7, 0.0), (0.1,) * 3)])
    return {
        "tracking": StateTracking(w, w[::-1]),
        "metric_tracking": StateTracking(w, w[::-1], robot.model),
        "terminal": TerminalStateTracking(np.concatenate([w, w]), robot.model)._stage(n),
        **{name: EFFORT_TERMS[name](w, robot, metric, True) for name in ("torque", "metric")},
        "limits": StateLimitPenalty(robot.q_min * 0.1, robot.q_max * 0.1, np.ones(n), 10.0),
        "clearance": ClearancePenalty(slots.clearance_function(), slots.values(), 0.8, 5.0),
    }


@pytest.mark.parametrize(
    "name", ["tracking", "metric_tracking", "terminal", "torque", "metric", "limits", "clearance"]
)
def test_each_costs_derivatives_are_those_of_its_expression(name: str) -> None:
    """The value and gradient a DDP reads equal the NLP's expression and its automatic
    derivative (seeded random points, planar2, 1e-10); the Hessian is the exact one for
    the quadratic terms and positive semi-definite for the others (Gauss-Newton)."""
    robot, metric = get_robot("planar2"), get_metric("planar2")
    n = robot.nv
    term = _terms(robot, metric, n)[name]
    s = _symbols(n)
    d = term.derivatives(s)
    z = ca.vertcat(s.x, s.u)
    expr = term.expression(s)
    grad_ad = ca.gradient(expr, z)
    hess_ad = ca.hessian(expr, z)[0]
    hess = ca.blockcat([[d.lxx, d.lux.T], [d.lux, d.luu]])
    ins = [s.x, s.u, s.q_ref, s.v_ref, s.effort_ref]
    f = ca.Function("f", ins, [expr, d.value, grad_ad, ca.vertcat(d.lx, d.lu), hess_ad, hess])
    rng = np.random.default_rng(7)
    for _ in range(10):
        point = [rng.normal(size=2 * n), 5 * rng.normal(size=n), rng.normal(size=n),
                 rng.normal(size=n), 5 * rng.normal(size=n)]  # fmt: skip
        e, v, g_ad, g, h_ad, h = (np.asarray(a) for a in f(*point))
        np.testing.assert_allclose(v, e, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(g, g_ad, rtol=1e-10, atol=1e-10)
        assert np.linalg.eigvalsh(0.5 * (h + h.T)).min() >= -1e-9
        if name in ("tracking", "metric_tracking", "terminal", "torque"):
            np.testing.assert_allclose(h, h_ad, rtol=1e-10, atol=1e-10)


def test_ddp_with_world_obstacles_combines_metric_effort_and_clearance() -> None:
    """``effort="metric"`` with ``obstacles`` and ``clearance_margin`` (refused before):
    holding a pose whose hand sphere is 3 cm from a ball, with a 5 cm margin, the cold
    solve's plan moves the hand out to about the margin (clearances by the slots' exact
    distance; the stiff penalty against the tracking cost leaves a few mm)."""
    import pinocchio as pin

    from geosyn.controllers import JointTrajectoryReference

    robot, metric = get_robot("planar2"), get_metric("planar2")
    q0 = np.array([0.3, -0.4])
    model, data = robot.model, robot.model.createData()
    pin.forwardKinematics(model, data, q0)
    hand = robot.collision_spheres()[-1]
    c = data.oMi[model.getJointId(hand.joint)].act(np.array(hand.center))
    out = c / np.linalg.norm(c)
    ball = Sphere(tuple(c + (hand.radius + 0.05 + 0.03) * out), 0.05)
    ref = JointTrajectoryReference(np.array([0.0, 2.0]), np.vstack([q0, q0]))
    ctl = mpc.GeodesicMPC(
        robot, metric, horizon=10, dt=0.05, control="torque", solver="ddp", effort="metric",
        reference=ref, clearance_margin=0.05, obstacles=[ball],
    )  # fmt: skip
    slots = ctl.obstacles
    assert slots is not None
    clearance = slots.clearance_function()

    def closest(q: np.ndarray) -> float:
        return float(np.min(np.asarray(clearance(q, slots.values())[0])))

    assert abs(closest(q0) - 0.03) < 1e-9
    ctl.reset(q0, np.zeros(2))
    plan = ctl.solve(0.0, q0, np.zeros(2))
    assert plan.success, plan.status
    assert closest(plan.x[-1, :2]) > 0.045, closest(plan.x[-1, :2])
    with pytest.raises(InvalidArgument, match="clearance_margin"):
        mpc.GeodesicMPC(robot, metric, horizon=3, control="torque", solver="ddp",
                        obstacles=[ball])  # fmt: skip
