"""Symbolic dynamics: inverse dynamics (RNEA), mass matrix (CRBA), forward dynamics (ABA)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import NamedTuple

import casadi as ca
import numpy as np
import pinocchio as pin

from geosyn.robots.symbolic.algebra import (
    _SE3,
    _ZERO3,
    _add,
    _cross,
    _div,
    _dot,
    _Force,
    _force_cross,
    _is_identity,
    _is_zero_vec,
    _madd,
    _madd6,
    _Mat3,
    _matmul,
    _matmul_symmetric,
    _matTvec,
    _matvec,
    _Motion,
    _motion_cross,
    _mul,
    _rotate_symmetric,
    _Scalar,
    _skew,
    _sub,
    _transpose,
    _vadd,
    _Vec3,
    _vscale,
)
from geosyn.robots.symbolic.model import (
    SXLike,
    _child_motion,
    _inertia_times,
    _Joint,
    _liMi,
    _mat,
    _Model,
    _parent_force,
    _parse_model,
    _scalars,
    _to_sx,
    _to_sx_column,
    _vec,
)


def _gravity(gravity: SXLike) -> _Vec3:
    g = _scalars(gravity, 3, "gravity")
    return (g[0], g[1], g[2])


_Recursion = Callable[[_Model, list[_Scalar], list[_Scalar], list[_Scalar], _Vec3], list[_Scalar]]


def _recursive(
    algorithm: _Recursion,
    model: pin.Model,
    q: SXLike,
    v: SXLike,
    u: tuple[SXLike, str],
    gravity: SXLike,
) -> ca.SX:
    """Check the arguments and run ``algorithm`` (``_rnea`` or ``_aba``).

    ``u`` is the third input and its argument name: ``(a, "a")`` or ``(tau, "tau")``.
    """
    m = _parse_model(model)
    out = algorithm(
        m,
        _scalars(q, model.nq, "q"),
        _scalars(v, model.nv, "v"),
        _scalars(u[0], model.nv, u[1]),
        _gravity(gravity),
    )
    return _to_sx_column(out)


def _forward_velocities(
    m: _Model,
    qs: list[_Scalar],
    vs: list[_Scalar],
    vel: list[_Motion],
    xs: dict[int, tuple[_SE3, _SE3]],
) -> Iterator[tuple[_Joint, tuple[_SE3, _SE3], _Motion, _Motion]]:
    """The forward pass shared by RNEA and ABA, base to tip, one joint per step.

    Fills ``xs[j.index]`` (parent <- joint transform) and ``vel[j.index]`` (body velocity)
    before yielding ``(joint, transform, joint velocity S qd, parent velocity in the joint
    frame)``; the caller's loop body runs before the next joint is built.
    """
    for j in m.joints:
        k = j.idx_v
        x = _liMi(j, qs[k])
        xs[j.index] = x
        vj = j.motion_subspace(vs[k])
        v_parent = _child_motion(x, vel[j.parent])
        vel[j.index] = _madd6(v_parent, vj)
        yield j, x, vj, v_parent


def _rnea(m: _Model, qs, vs, accs, g: _Vec3) -> list[_Scalar]:
    n = m.njoints
    vel: list[_Motion] = [(_ZERO3, _ZERO3)] * n
    # Gravity enters as an upward acceleration of the base (Pinocchio's a_gf[0] = -g).
    acc: list[_Motion] = [(_vscale(-1.0, g), _ZERO3)] * n
    force: list[_Force] = [(_ZERO3, _ZERO3)] * n
    xs: dict[int, tuple[_SE3, _SE3]] = {}
    for j, x, vj, v_parent in _forward_velocities(m, qs, vs, vel, xs):
        k = j.idx_v
        # v x vJ == (v_parent + vJ) x vJ == v_parent x vJ
        a = _madd6(_child_motion(x, acc[j.parent]), j.motion_subspace(accs[k]))
        acc[j.index] = _madd6(a, _motion_cross(v_parent, vj))
        f = _inertia_times(j, acc[j.index])
        bf = _force_cross(vel[j.index], _inertia_times(j, vel[j.index]))
        force[j.index] = _madd6(f, bf)
    tau: list[_Scalar] = [0.0] * m.nv
    for j in reversed(m.joints):
        f = force[j.index]
        tau[j.idx_v] = _add(j.project(f), _mul(j.armature, accs[j.idx_v]))
        if j.parent != 0:
            force[j.parent] = _madd6(force[j.parent], _parent_force(xs[j.index], f))
    return tau


def rnea(model: pin.Model, q: SXLike, v: SXLike, a: SXLike, gravity: SXLike) -> ca.SX:
    """Inverse dynamics by the recursive Newton-Euler algorithm, like ``pin.rnea``.

    .. math::
        \\tau = M(q)\\, a + C(q, v)\\, v + g(q)

    with ``M`` including ``diag(model.armature)``.

    Args:
        model: Pinocchio model (fixed base, supported joint types only).
        q: (nq,) joint positions [rad or m], SX or numeric.
        v: (nv,) joint velocities [rad/s or m/s], SX or numeric.
        a: (nv,) joint accelerations [rad/s^2 or m/s^2], SX or numeric.
        gravity: (3,) gravity acceleration in the world frame [m/s^2], e.g.
            ``(0, 0, -9.81)``; SX or numeric (numeric zeros shrink the graph).

    Returns:
        (nv, 1) SX joint torques/forces [N m or N].

    Raises:
        InvalidArgument: unsupported model or a wrong shape.
    """
    return _recursive(_rnea, model, q, v, (a, "a"), gravity)


def bias(model: pin.Model, q: SXLike, v: SXLike, gravity: SXLike) -> ca.SX:
    """Nonlinear effects ``C(q, v) v + g(q)``: :func:`rnea` with zero acceleration.

    Args:
        model: Pinocchio model (fixed base, supported joint types only).
        q: (nq,) joint positions [rad or m], SX or numeric.
        v: (nv,) joint velocities [rad/s or m/s], SX or numeric.
        gravity: (3,) gravity acceleration in the world frame [m/s^2].

    Returns:
        (nv, 1) SX bias torques/forces [N m or N].

    Raises:
        InvalidArgument: unsupported model or a wrong shape.
    """
    return rnea(model, q, v, np.zeros(model.nv), gravity)


def _composite_transform(x: tuple[_SE3, _SE3], y: tuple) -> tuple:
    """Rigid-body inertia (mass, first moment h = m c, inertia about origin) to parent."""
    for t in (x[1], x[0]):
        mass, h, io = y
        r, p = t.rotation, t.translation
        hr = _matvec(r, h)
        io = _rotate_symmetric(r, io)
        if not _is_zero_vec(p):
            # I_O' = R I_O R^T - (p h^T + h p^T) + 2 (h.p) I - m (p p^T - |p|^2 I)
            hp2 = _mul(2.0, _dot(hr, p))
            mp = _vscale(mass, p)
            mpp = _dot(mp, p)
            up = {}
            for i in range(3):
                for j in range(i, 3):
                    e = _sub(io[i][j], _add(_mul(p[i], hr[j]), _mul(hr[i], p[j])))
                    e = _sub(e, _mul(mp[i], p[j]))
                    if i == j:
                        e = _add(e, _add(hp2, mpp))
                    up[i, j] = e
            io = tuple(tuple(up[min(i, j), max(i, j)] for j in range(3)) for i in range(3))
            hr = _vadd(hr, mp)
        y = (mass, hr, io)
    return y


def crba(model: pin.Model, q: SXLike) -> ca.SX:
    """Joint-space mass matrix by the composite rigid body algorithm, like ``pin.crba``.

    Unlike ``pin.crba`` (upper triangle only) the result is the full symmetric matrix;
    ``diag(model.armature)`` is included.

    Args:
        model: Pinocchio model (fixed base, supported joint types only).
        q: (nq,) joint positions [rad or m], SX or numeric.

    Returns:
        (nv, nv) SX symmetric positive definite mass matrix [kg m^2, kg m or kg].

    Raises:
        InvalidArgument: unsupported model or wrong shape of ``q``.
    """
    m = _parse_model(model)
    qs = _scalars(q, model.nq, "q")
    xs = {j.index: _liMi(j, qs[j.idx_v]) for j in m.joints}
    by_index = {j.index: j for j in m.joints}
    composite: dict[int, tuple] = {}
    for j in m.joints:
        c = np.asarray(j.com)
        io = np.asarray(j.inertia_com) + j.mass * (np.dot(c, c) * np.eye(3) - np.outer(c, c))
        composite[j.index] = (j.mass, _vec(j.mass * c), _mat(io))
    for j in reversed(m.joints):
        if j.parent != 0:
            mass, h, io = _composite_transform(xs[j.index], composite[j.index])
            pm, ph, pio = composite[j.parent]
            composite[j.parent] = (mass + pm, _vadd(h, ph), _madd(io, pio))
    big: list[list[_Scalar]] = [[0.0] * m.nv for _ in range(m.nv)]
    for j in m.joints:
        mass, h, io = composite[j.index]
        ax = j.axis
        if j.prismatic:
            f: _Force = (_vscale(mass, ax), _cross(h, ax))
        else:
            f = (_cross(ax, h), _matvec(io, ax))
        big[j.idx_v][j.idx_v] = _add(j.project(f), j.armature)
        i = j.index
        while by_index[i].parent != 0:
            f = _parent_force(xs[i], f)
            i = by_index[i].parent
            e = by_index[i].project(f)
            big[by_index[i].idx_v][j.idx_v] = e
            big[j.idx_v][by_index[i].idx_v] = e
    return _to_sx(big)


class _Articulated(NamedTuple):
    """Symmetric 6x6 articulated inertia [[A, B], [B^T, C]] (linear first)."""

    a: _Mat3
    b: _Mat3
    c: _Mat3

    def times(self, m: _Motion) -> _Force:
        lin, ang = m
        return (
            _vadd(_matvec(self.a, lin), _matvec(self.b, ang)),
            _vadd(_matTvec(self.b, lin), _matvec(self.c, ang)),
        )

    def to_parent(self, x: tuple[_SE3, _SE3]) -> _Articulated:
        """``X* Y X*^T`` for the joint's parent <- child transform."""
        a, b, c = self.a, self.b, self.c
        for t in (x[1], x[0]):
            r, p = t.rotation, t.translation
            if not _is_identity(r):
                rt = _transpose(r)
                a = _rotate_symmetric(r, a)
                b = _matmul(_matmul(r, b), rt)
                c = _rotate_symmetric(r, c)
            if not _is_zero_vec(p):
                # T = [[I, 0], [P, I]], P = [p]x:  B' = B - A P,
                # C' = C + P B + (P B)^T - P A P
                pk = _skew(p)
                pb = _matmul(pk, b)
                pap = _matmul_symmetric(_matmul(pk, a), pk)
                b = tuple(
                    tuple(
                        _sub(b[i][j], _dot(a[i], (pk[0][j], pk[1][j], pk[2][j]))) for j in range(3)
                    )
                    for i in range(3)
                )  # type: ignore[assignment]
                up = {
                    (i, j): _sub(_add(c[i][j], _add(pb[i][j], pb[j][i])), pap[i][j])
                    for i in range(3)
                    for j in range(i, 3)
                }
                c = tuple(tuple(up[min(i, j), max(i, j)] for j in range(3)) for i in range(3))  # type: ignore[assignment]
        return _Articulated(a, b, c)

    def __add__(self, other: object) -> _Articulated:
        if not isinstance(other, _Articulated):
            return NotImplemented
        return _Articulated(_madd(self.a, other.a), _madd(self.b, other.b), _madd(self.c, other.c))


def _block_sub(m: _Mat3, big: list[list[_Scalar]], row: int, col: int) -> _Mat3:
    """``m - big[row:row + 3, col:col + 3]``."""
    return tuple(  # type: ignore[return-value]
        tuple(_sub(m[r][c], big[r + row][c + col]) for c in range(3)) for r in range(3)
    )


def _body_articulated(j: _Joint) -> _Articulated:
    c = np.asarray(j.com)
    ck = np.array([[0.0, -c[2], c[1]], [c[2], 0.0, -c[0]], [-c[1], c[0], 0.0]])
    return _Articulated(
        _mat(j.mass * np.eye(3)),
        _mat(-j.mass * ck),
        _mat(np.asarray(j.inertia_com) - j.mass * ck @ ck),
    )


def _aba(m: _Model, qs, vs, taus, g: _Vec3) -> list[_Scalar]:
    n = m.njoints
    xs: dict[int, tuple[_SE3, _SE3]] = {}
    vel: list[_Motion] = [(_ZERO3, _ZERO3)] * n
    bias_acc: list[_Motion] = [(_ZERO3, _ZERO3)] * n
    inertia: dict[int, _Articulated] = {}
    pa: dict[int, _Force] = {}
    for j, _x, vj, v_parent in _forward_velocities(m, qs, vs, vel, xs):
        bias_acc[j.index] = _motion_cross(v_parent, vj)
        inertia[j.index] = _body_articulated(j)
        pa[j.index] = _force_cross(vel[j.index], _inertia_times(j, vel[j.index]))
    u_vec: dict[int, _Force] = {}
    d_inv: dict[int, _Scalar] = {}
    u: dict[int, _Scalar] = {}
    for j in reversed(m.joints):
        i = j.index
        ia = inertia[i]
        uu = ia.times(j.motion_subspace(1.0))
        di = _div(1.0, _add(j.project(uu), j.armature))
        ui = _sub(taus[j.idx_v], j.project(pa[i]))
        u_vec[i], d_inv[i], u[i] = uu, di, ui
        if j.parent != 0:
            flat = [*uu[0], *uu[1]]
            scaled = [_mul(e, di) for e in flat]
            # Ia^A = Ia - U U^T / D
            sub = [[_mul(scaled[r], flat[c]) for c in range(6)] for r in range(6)]
            ia_a = _Articulated(
                _block_sub(ia.a, sub, 0, 0),
                _block_sub(ia.b, sub, 0, 3),
                _block_sub(ia.c, sub, 3, 3),
            )
            ud = _mul(ui, di)
            pa_a = _madd6(
                _madd6(pa[i], ia_a.times(bias_acc[i])),
                (_vscale(ud, uu[0]), _vscale(ud, uu[1])),
            )
            inertia[j.parent] = inertia[j.parent] + ia_a.to_parent(xs[i])
            pa[j.parent] = _madd6(pa[j.parent], _parent_force(xs[i], pa_a))
    acc: list[_Motion] = [(_vscale(-1.0, g), _ZERO3)] * n
    qdd: list[_Scalar] = [0.0] * m.nv
    for j in m.joints:
        i = j.index
        a = _madd6(_child_motion(xs[i], acc[j.parent]), bias_acc[i])
        uu = u_vec[i]
        qdd_i = _mul(_sub(u[i], _add(_dot(uu[0], a[0]), _dot(uu[1], a[1]))), d_inv[i])
        qdd[j.idx_v] = qdd_i
        acc[i] = _madd6(a, j.motion_subspace(qdd_i))
    return qdd


def aba(model: pin.Model, q: SXLike, v: SXLike, tau: SXLike, gravity: SXLike) -> ca.SX:
    """Forward dynamics by the articulated body algorithm, like ``pin.aba``.

    .. math::
        a = M(q)^{-1} \\left(\\tau - C(q, v)\\, v - g(q)\\right)

    with ``M`` including ``diag(model.armature)``, computed without forming ``M^{-1}``.
    With zero gravity and zero torque this is the geodesic acceleration of the
    kinetic-energy metric, :math:`-\\Gamma(q)(v, v)`.

    Args:
        model: Pinocchio model (fixed base, supported joint types only).
        q: (nq,) joint positions [rad or m], SX or numeric.
        v: (nv,) joint velocities [rad/s or m/s], SX or numeric.
        tau: (nv,) joint torques/forces [N m or N], SX or numeric.
        gravity: (3,) gravity acceleration in the world frame [m/s^2]; SX or numeric.

    Returns:
        (nv, 1) SX joint accelerations [rad/s^2 or m/s^2].

    Raises:
        InvalidArgument: unsupported model or a wrong shape.
    """
    return _recursive(_aba, model, q, v, (tau, "tau"), gravity)
