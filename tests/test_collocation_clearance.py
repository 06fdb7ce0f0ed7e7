"""Structured first and second derivatives of the collocation's clearances
(`geosyn.metrics.geodesic.collocation_clearance`).

Reference: CasADi's automatic differentiation of the whole smooth-minimum clearance
(`ObstacleTerm.symbolic_clearances`), at seeded configurations and multipliers.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from geosyn.metrics.geodesic.collocation_clearance import clearance_hessian, clearance_jacobian
from geosyn.metrics.shaping import ObstacleTerm
from geosyn.robots import load_robot
from geosyn.world import Box, Capsule, HalfSpace, Sphere


def _term(distance: str) -> ObstacleTerm:
    robot = load_robot("panda")
    c, s = np.cos(0.4), np.sin(0.4)
    obstacles = [
        Sphere((0.45, 0.1, 0.45), 0.1),
        Box((0.3, -0.3, 0.3), (0.1, 0.05, 0.2), np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])),
        Capsule((0.2, 0.4, 0.6), (0.6, 0.4, 0.2), 0.04),
        HalfSpace((0.0, 0.0, 1.0), -0.05),
    ]  # and one empty slot
    return ObstacleTerm(obstacles, capacity=5, distance=distance).bind(robot)


@pytest.mark.parametrize("distance", ["exact", "smooth"])
def test_structured_hessian_equals_automatic_differentiation(distance: str) -> None:
    term = _term(distance)
    robot = term.robot
    k = 300.0  # a softer minimum than the default: more spheres weigh in
    hess = clearance_hessian(term, k)
    q, lam = ca.SX.sym("q", robot.nq), ca.SX.sym("lam", term.capacity)
    pc = term.symbolic_parameters()
    expr = ca.hessian(ca.dot(lam, term.symbolic_clearances(q, k)), q)[0]
    ref = ca.Function("ref", [q, pc, lam], [ca.densify(expr)])
    rng = np.random.default_rng(7)
    for _ in range(20):
        qv = robot.random_q(rng)
        lv = rng.standard_normal(term.capacity)
        H = np.asarray(hess(qv, term.parameter_values(), lv))
        R = np.asarray(ref(qv, term.parameter_values(), lv))
        assert np.abs(H - R).max() <= 1e-9 * max(1.0, np.abs(R).max())
        np.testing.assert_allclose(H, H.T, atol=1e-12 * max(1.0, np.abs(R).max()))
    assert hess.n_instructions() < ref.n_instructions()


def test_structured_jacobian_equals_automatic_differentiation() -> None:
    term = _term("exact")
    k = 1000.0
    jac = clearance_jacobian(term, k)
    q = ca.SX.sym("q", term.n)
    pc = term.symbolic_parameters()
    c = term.symbolic_clearances(q, k)
    ref = ca.Function("ref", [q, pc], [c, ca.densify(ca.jacobian(c, q))])
    rng = np.random.default_rng(8)
    for _ in range(20):
        qv = term.robot.random_q(rng)
        (c1, J1), (c2, J2) = jac(qv, term.parameter_values()), ref(qv, term.parameter_values())
        np.testing.assert_allclose(np.asarray(c1), np.asarray(c2), rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.asarray(J1), np.asarray(J2), rtol=0, atol=1e-10)
    assert np.asarray(J1)[-1].tolist() == [0.0] * term.n  # the empty slot
    assert jac.n_instructions() < ref.n_instructions()
