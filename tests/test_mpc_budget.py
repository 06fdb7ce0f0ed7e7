"""The MPC's per-solve wall-time budget and its refusal of states far outside the OCP's
bounds: each ends in a flagged fallback, never in a hang or a silent result (issue 15)."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import get_metric, get_robot
from geosyn.controllers.mpc import GeodesicMPC
from geosyn.controllers.mpc.ocp.settings import STATE_MARGIN
from geosyn.controllers.reference import GeodesicReference
from geosyn.core import InvalidArgument
from geosyn.synergies.synergy import GeodesicSynergy


def _mpc(**kw) -> tuple[GeodesicMPC, np.ndarray, np.ndarray]:
    robot, metric = get_robot("planar2"), get_metric("planar2")
    q0 = np.array([0.3, -0.4])
    ref = GeodesicReference(
        GeodesicSynergy(metric, q0, np.array([0.4, 0.4])), duration=1.0, steps=100
    )
    mpc = GeodesicMPC(robot, metric, horizon=10, dt=0.02, control="torque", reference=ref, **kw)
    mpc.reset(q0, np.array([0.4, 0.4]))
    return mpc, q0, np.array([0.4, 0.4])


def _check_fallback(mpc: GeodesicMPC, tau: np.ndarray) -> None:
    d = mpc.diagnostics
    assert d.fallback_used and d.extra["fallback"] == 2.0  # no plan yet: computed torque
    assert np.all(np.abs(tau) <= mpc.robot.tau_max + 1e-12)
    assert mpc.plan is None


def test_absurd_velocity_is_not_solved_and_falls_back() -> None:
    mpc, q0, _ = _mpc()
    v = np.array([200.0, -3.0])  # rad/s; planar2's v_max is 10 rad/s
    tau = mpc.compute(0.0, q0, v)
    d = mpc.diagnostics
    assert d.solver_status.startswith("skipped: measured state |v[0]| = 200")
    assert d.iterations == 0
    _check_fallback(mpc, tau)
    # Just inside the margin the solver runs (and here succeeds).
    v_ok = (1.0 + STATE_MARGIN[1]) * mpc.robot.v_max * np.array([0.2, 0.1])
    mpc.reset(q0, v_ok)
    mpc.compute(0.0, q0, v_ok)
    assert not mpc.diagnostics.solver_status.startswith("skipped")
    assert mpc.diagnostics.iterations >= 1


def test_position_far_outside_the_limits_is_not_solved() -> None:
    robot = get_robot("planar2")
    if not np.isfinite(robot.q_max[0]):  # planar2 joints are unlimited: use a copy
        import dataclasses

        robot = dataclasses.replace(robot, q_min=np.full(2, -1.0), q_max=np.full(2, 1.0))
    mpc = GeodesicMPC(robot, get_metric("planar2"), horizon=10, dt=0.02, control="torque")
    _, q0, v0 = _mpc()
    mpc.set_reference(GeodesicReference(GeodesicSynergy(get_metric("planar2"), q0, v0)))
    q = np.array([robot.q_max[0] + STATE_MARGIN[0] + 0.05, 0.0])
    mpc.reset(q, v0)
    mpc.compute(0.0, q, v0)
    assert mpc.diagnostics.solver_status.startswith("skipped: measured state q[0]")
    assert mpc.diagnostics.fallback_used


@pytest.mark.parametrize(
    "solver, words", [("ipopt", "Maximum_WallTime"), ("fatrop", "over budget")]
)
def test_solve_over_its_budget_falls_back(solver: str, words: str) -> None:
    mpc, q0, v0 = _mpc(solver=solver, max_solve_time=1e-7)
    tau = mpc.compute(0.0, q0 + 0.01, v0)
    assert words in mpc.diagnostics.solver_status, mpc.diagnostics.solver_status
    _check_fallback(mpc, tau)


def test_budget_is_validated() -> None:
    with pytest.raises(InvalidArgument, match="max_solve_time"):
        _mpc(max_solve_time=0.0)
