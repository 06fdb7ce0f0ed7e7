"""First and second derivatives of the collocation's smooth-minimum clearances, by their
structure.

Part of `geosyn.metrics.geodesic.collocation`. The clearance of a configuration ``q``
against obstacle slot ``o`` is the smooth minimum over the robot spheres ``s`` of
``d_so = sd_o(x_s(q)) - r_s``, ``c_o = -log(sum_s exp(-k d_so)) / k``. With
``w_so = exp(-k (d_so - c_o))`` (they sum to 1 over ``s``), ``n_so = d sd_o / dx`` and
``J_s = dx_s / dq``, the gradient of ``c_o`` is ``g_o`` below and the Hessian of
``sum_o mu_o c_o`` is

.. math:: \\sum_s J_s^T M_s J_s
          + \\nabla^2_q \\Big(\\sum_s \\beta_s \\cdot x_s(q)\\Big)\\Big|_{\\beta\\ fixed}
          + k \\sum_o \\mu_o\\, g_o g_o^T ,

.. math:: M_s = \\sum_o \\mu_o w_{so} \\big(\\nabla^2_x sd_o - k\\, n_{so} n_{so}^T\\big),
          \\quad \\beta_s = \\sum_o \\mu_o w_{so} n_{so},
          \\quad g_o = \\sum_s w_{so} J_s^T n_{so} .

The middle term needs the second derivatives of the joint placements only, weighted per
joint (``sum_j <R_j(q), A_j> + b_j . p_j(q)`` with ``A_j = sum_{s on j} beta_s c_s^T``,
``b_j = sum_{s on j} beta_s``, ``c_s`` the sphere's centre in its joint frame), not of
every sphere centre; the distances' derivatives are taken in 3-D. The results are the
exact Jacobian and Hessian (tested against automatic differentiation of the whole
clearance), as expression graphs about half the size of the latter's.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import casadi as ca

from geosyn.metrics.shaping.obstacle import (
    DISTANCES,
    INACTIVE_CLEARANCE,
    PARAMS_PER_OBSTACLE,
)

if TYPE_CHECKING:
    from geosyn.metrics.shaping.obstacle import ObstacleTerm

__all__ = ["clearance_hessian", "clearance_jacobian"]


def _sphere_pairs(
    clearance: ObstacleTerm, q: ca.SX, pc: ca.SX, *, hessian: bool
) -> tuple[list[tuple[ca.SX, ca.SX]], list[Any]]:
    """Joint placements, and per robot sphere (joint id, local centre, J_s, and per slot
    (d_so, n_so[, Hessian of sd_o in x])) as SX of ``q`` and ``pc``."""
    from geosyn.robots import symbolic

    robot, P = clearance.robot, PARAMS_PER_OBSTACLE
    xs, prm = ca.SX.sym("x", 3), ca.SX.sym("prm", P - 1)
    sd = DISTANCES[clearance.distance]()(xs, prm)[0]
    hx, gx = ca.hessian(sd, xs)
    outs = [sd, gx, hx] if hessian else [sd, gx]
    dist = ca.Function("sphere_distance", [xs, prm], outs)
    oMi = symbolic.joint_placements(robot.model, q)
    spheres = []
    for s in clearance.spheres:
        jid = robot.joint_id(s.joint)
        R, p = oMi[jid]
        x = ca.mtimes(R, ca.DM(s.center)) + p
        pairs = []
        for o in range(clearance.capacity):
            d, *rest = dist(x, pc[o * P : o * P + P - 1])
            pairs.append((d - s.radius, *rest))
        spheres.append((jid, s.center, ca.jacobian(x, q), pairs))
    return oMi, spheres


def clearance_jacobian(clearance: ObstacleTerm, softmin: float) -> ca.Function:
    """``colloc_clearance_j(q, pc) -> (c (capacity,), dc/dq (capacity, n))``.

    ``c`` as in `clearance_hessian`; row ``o`` of the Jacobian is ``g_o`` of the module
    docstring (zero on empty slots). Builds SX graphs (allocates).
    """
    n, cap, k, P = clearance.n, clearance.capacity, softmin, PARAMS_PER_OBSTACLE
    q = ca.SX.sym("q", n)
    pc = clearance.symbolic_parameters()
    _, spheres = _sphere_pairs(clearance, q, pc, hessian=False)
    rows, jac = [], []
    for o in range(cap):
        d = ca.vertcat(*[pairs[o][0] for *_, pairs in spheres])
        low = ca.mmin(d)
        smooth = low - ca.log(ca.sum1(ca.exp(-k * (d - low)))) / k
        g_o = ca.SX.zeros(n)
        for _, _, J, pairs in spheres:
            if J.nnz():
                g_o = g_o + ca.exp(-k * (pairs[o][0] - smooth)) * ca.mtimes(J.T, pairs[o][1])
        active = pc[o * P + P - 1]
        rows.append(active * smooth + (1.0 - active) * INACTIVE_CLEARANCE)
        jac.append(active * g_o.T)
    return ca.Function("colloc_clearance_j", [q, pc],
                       [ca.vertcat(*rows), ca.densify(ca.vertcat(*jac))], {"cse": True})  # fmt: skip


def clearance_hessian(clearance: ObstacleTerm, softmin: float) -> ca.Function:
    """``colloc_clearance_d(q, pc, lam) -> (n, n)``: Hessian of ``lam . c(q)``.

    ``c`` is ``clearance.symbolic_clearances(q, softmin)`` (one smooth minimum per slot,
    `INACTIVE_CLEARANCE` on empty slots); ``pc`` its parameters; ``lam``: (capacity,).
    Builds SX graphs (allocates).
    """
    n, cap, k, P = clearance.n, clearance.capacity, softmin, PARAMS_PER_OBSTACLE
    q = ca.SX.sym("q", n)
    pc = clearance.symbolic_parameters()
    lam = ca.SX.sym("lam", cap)
    oMi, spheres = _sphere_pairs(clearance, q, pc, hessian=True)
    H = ca.SX.zeros(n, n)
    beta = [ca.SX.zeros(3) for _ in spheres]
    M = [ca.SX.zeros(3, 3) for _ in spheres]
    for o in range(cap):
        d = ca.vertcat(*[pairs[o][0] for *_, pairs in spheres])
        low = ca.mmin(d)
        smooth = low - ca.log(ca.sum1(ca.exp(-k * (d - low)))) / k
        mu = lam[o] * pc[o * P + P - 1]  # zero on an empty slot (its clearance is constant)
        g_o = ca.SX.zeros(n)
        for i, (_, _, J, pairs) in enumerate(spheres):
            if J.nnz() == 0:  # a sphere fixed to the base: no derivatives
                continue
            _, nrm, hs = pairs[o]
            w = ca.exp(-k * (pairs[o][0] - smooth))
            beta[i] = beta[i] + (mu * w) * nrm
            M[i] = M[i] + (mu * w) * (hs - k * ca.mtimes(nrm, nrm.T))
            g_o = g_o + w * ca.mtimes(J.T, nrm)
        H = H + (k * mu) * ca.mtimes(g_o, g_o.T)
    for i, (_, _, J, _) in enumerate(spheres):
        if J.nnz():
            H = H + ca.mtimes(J.T, ca.mtimes(M[i], J))
    # kinematic curvature: sum_s beta_s . x_s(q), aggregated per joint, beta held fixed
    joints = sorted({jid for jid, _, J, _ in spheres if J.nnz()})
    A_sym = {j: ca.SX.sym(f"A{j}", 3, 3) for j in joints}
    b_sym = {j: ca.SX.sym(f"b{j}", 3) for j in joints}
    psi = sum((ca.dot(oMi[j][0], A_sym[j]) + ca.dot(oMi[j][1], b_sym[j]) for j in joints), ca.SX(0))
    kin = ca.Function("kinematic_curvature", [q, *A_sym.values(), *b_sym.values()],
                      [ca.hessian(psi, q)[0]])  # fmt: skip
    A_val = {j: ca.SX.zeros(3, 3) for j in joints}
    b_val = {j: ca.SX.zeros(3) for j in joints}
    for i, (jid, center, J, _) in enumerate(spheres):
        if J.nnz():
            A_val[jid] = A_val[jid] + ca.mtimes(beta[i], ca.DM(center).T)
            b_val[jid] = b_val[jid] + beta[i]
    H = H + kin(q, *A_val.values(), *b_val.values())
    return ca.Function("colloc_clearance_d", [q, pc, lam], [ca.densify(H)], {"cse": True})
