"""Scalar, 3-vector and spatial algebra on CasADi SX with constant folding.

A scalar while a graph is built is a Python float (a constant that can still be folded)
or a 1x1 SX expression. A product with a constant 0 is never created, a product with +-1
is a copy or a negation, and sums with 0 are dropped, so graphs stay small. Spatial
motions and forces are pairs of 3-vectors (linear first), expressed in a joint's frame.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import casadi as ca

# A scalar while the graph is built: a Python float (a constant that can still be folded)
# or a 1x1 SX expression.
_Scalar = float | ca.SX
_Vec3 = tuple[_Scalar, _Scalar, _Scalar]
_Mat3 = tuple[_Vec3, _Vec3, _Vec3]  # rows
_Motion = tuple[_Vec3, _Vec3]  # (linear, angular)
_Force = tuple[_Vec3, _Vec3]  # (force, torque)

# --------------------------------------------------------------------------------------
# Scalar and 3-vector algebra with constant folding.
# --------------------------------------------------------------------------------------


def _mul(a: _Scalar, b: _Scalar) -> _Scalar:
    if isinstance(a, float):
        if a == 0.0:
            return 0.0
        if isinstance(b, float):
            return a * b
        if a == 1.0:
            return b
        if a == -1.0:
            return -b
        return a * b
    if isinstance(b, float):
        if b == 0.0:
            return 0.0
        if b == 1.0:
            return a
        if b == -1.0:
            return -a
    return a * b


def _add(a: _Scalar, b: _Scalar) -> _Scalar:
    if isinstance(a, float):
        if a == 0.0:
            return b
        if isinstance(b, float):
            return a + b
    elif isinstance(b, float) and b == 0.0:
        return a
    return a + b


def _sub(a: _Scalar, b: _Scalar) -> _Scalar:
    if isinstance(b, float):
        if b == 0.0:
            return a
        if isinstance(a, float):
            return a - b
    elif isinstance(a, float) and a == 0.0:
        return -b
    return a - b


def _div(a: _Scalar, b: _Scalar) -> _Scalar:
    if isinstance(a, float) and a == 0.0:
        return 0.0
    if isinstance(b, float) and b == 1.0:
        return a
    return a / b


def _sum(terms: Sequence[_Scalar]) -> _Scalar:
    out: _Scalar = 0.0
    for t in terms:
        out = _add(out, t)
    return out


def _dot(a: Sequence[_Scalar], b: Sequence[_Scalar]) -> _Scalar:
    return _sum([_mul(x, y) for x, y in zip(a, b, strict=True)])


def _vadd(a: _Vec3, b: _Vec3) -> _Vec3:
    return (_add(a[0], b[0]), _add(a[1], b[1]), _add(a[2], b[2]))


def _vsub(a: _Vec3, b: _Vec3) -> _Vec3:
    return (_sub(a[0], b[0]), _sub(a[1], b[1]), _sub(a[2], b[2]))


def _vscale(s: _Scalar, a: _Vec3) -> _Vec3:
    return (_mul(s, a[0]), _mul(s, a[1]), _mul(s, a[2]))


def _cross(a: _Vec3, b: _Vec3) -> _Vec3:
    return (
        _sub(_mul(a[1], b[2]), _mul(a[2], b[1])),
        _sub(_mul(a[2], b[0]), _mul(a[0], b[2])),
        _sub(_mul(a[0], b[1]), _mul(a[1], b[0])),
    )


def _matvec(m: _Mat3, x: _Vec3) -> _Vec3:
    return (_dot(m[0], x), _dot(m[1], x), _dot(m[2], x))


def _matTvec(m: _Mat3, x: _Vec3) -> _Vec3:
    return (
        _dot((m[0][0], m[1][0], m[2][0]), x),
        _dot((m[0][1], m[1][1], m[2][1]), x),
        _dot((m[0][2], m[1][2], m[2][2]), x),
    )


def _transpose(m: _Mat3) -> _Mat3:
    return (
        (m[0][0], m[1][0], m[2][0]),
        (m[0][1], m[1][1], m[2][1]),
        (m[0][2], m[1][2], m[2][2]),
    )


def _matmul(a: _Mat3, b: _Mat3) -> _Mat3:
    bt = _transpose(b)
    return tuple(tuple(_dot(a[i], bt[j]) for j in range(3)) for i in range(3))  # type: ignore[return-value]


def _matmul_symmetric(a: _Mat3, b: _Mat3) -> _Mat3:
    """``a @ b`` for a product known to be symmetric: only the upper triangle is built."""
    bt = _transpose(b)
    up = {(i, j): _dot(a[i], bt[j]) for i in range(3) for j in range(i, 3)}
    return tuple(tuple(up[min(i, j), max(i, j)] for j in range(3)) for i in range(3))  # type: ignore[return-value]


def _madd(a: _Mat3, b: _Mat3) -> _Mat3:
    return tuple(tuple(_add(a[i][j], b[i][j]) for j in range(3)) for i in range(3))  # type: ignore[return-value]


def _skew(p: _Vec3) -> _Mat3:
    return ((0.0, -p[2], p[1]), (p[2], 0.0, -p[0]), (-p[1], p[0], 0.0))


def _rotate_symmetric(r: _Mat3, s: _Mat3) -> _Mat3:
    """``r @ s @ r.T`` for a symmetric ``s``."""
    return _matmul_symmetric(_matmul(r, s), _transpose(r))


_IDENTITY: _Mat3 = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
_ZERO3: _Vec3 = (0.0, 0.0, 0.0)


def _is_const(x: Sequence[_Scalar], value: Sequence[_Scalar]) -> bool:
    # Never compare SX with ==: that builds an expression instead of answering.
    return all(isinstance(e, float) and e == c for e, c in zip(x, value, strict=True))


def _is_zero_vec(p: _Vec3) -> bool:
    return _is_const(p, _ZERO3)


def _is_identity(r: _Mat3) -> bool:
    return all(_is_const(r[i], _IDENTITY[i]) for i in range(3))


# --------------------------------------------------------------------------------------
# Rigid transforms (R, p): x_parent = R x_child + p.
# --------------------------------------------------------------------------------------


class _SE3(NamedTuple):
    rotation: _Mat3
    translation: _Vec3


_SE3_IDENTITY = _SE3(_IDENTITY, _ZERO3)


def _se3_compose(a: _SE3, b: _SE3) -> _SE3:
    return _SE3(
        _matmul(a.rotation, b.rotation),
        _vadd(_matvec(a.rotation, b.translation), a.translation),
    )


def _motion_act_inv(x: _SE3, m: _Motion) -> _Motion:
    """A motion given in the parent frame, expressed in the child frame of ``x``."""
    lin, ang = m
    return (
        _matTvec(x.rotation, _vadd(lin, _cross(ang, x.translation))),
        _matTvec(x.rotation, ang),
    )


def _force_act(x: _SE3, f: _Force) -> _Force:
    """A force given in the child frame of ``x``, expressed in the parent frame."""
    force = _matvec(x.rotation, f[0])
    return force, _vadd(_matvec(x.rotation, f[1]), _cross(x.translation, force))


def _motion_cross(m: _Motion, n: _Motion) -> _Motion:
    """Spatial motion cross product ``m x n``."""
    return (
        _vadd(_cross(m[1], n[0]), _cross(m[0], n[1])),
        _cross(m[1], n[1]),
    )


def _force_cross(m: _Motion, f: _Force) -> _Force:
    """Spatial motion-force cross product ``m x* f``."""
    return (
        _cross(m[1], f[0]),
        _vadd(_cross(m[1], f[1]), _cross(m[0], f[0])),
    )


def _madd6(a: _Motion, b: _Motion) -> _Motion:
    return _vadd(a[0], b[0]), _vadd(a[1], b[1])
