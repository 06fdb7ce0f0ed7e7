"""Symbolic rigid-body algorithms in CasADi SX, built from a ``pinocchio.Model``.

Pinocchio's PyPI wheel ships without ``pinocchio.casadi``, so geosyn keeps its own small
symbolic versions of the algorithms it needs: inverse dynamics (RNEA), the joint-space
mass matrix (CRBA), forward dynamics (ABA), frame placements and frame Jacobians. Each is
a pure function of the model and CasADi ``SX`` expressions and returns ``SX``; the results
match Pinocchio's numerical algorithms to round-off (tested to 1e-12 relative).

Supported models: fixed base, ``nq == nv``, every joint one of ``JointModelRX/RY/RZ``,
``JointModelRevoluteUnaligned``, ``JointModelPX/PY/PZ``, ``JointModelPrismaticUnaligned``.
``model.armature`` is included the way Pinocchio includes it (added to the diagonal of
the mass matrix).

Graphs are kept small by working with 3-vectors (linear, angular) instead of 6x6 spatial
matrices, by writing a revolute joint's rotation with one ``cos``/``sin`` pair, and by
folding constants while the graph is built: a product with a constant 0 is never created,
a product with +-1 is a copy or a negation, and numeric inputs (for example a zero gravity
or a zero torque) are propagated as Python floats. Entries of the model's constant joint
rotations within 1e-14 of 0 or +-1 (the ``6e-17`` of a URDF ``rpy`` of pi/2) are snapped
to exactly 0 or +-1 so that they fold too; this changes results by ~1e-16 relative.

Conventions follow Pinocchio: spatial motions and forces are expressed in the local frame
of their joint with the linear part first, and Jacobians have the linear rows first.

Typical use (build once, call often)::

    fns = dynamics_functions(model, gravity=np.array([0.0, 0.0, -9.81]))
    M = fns.M(q)                       # casadi.DM (nv, nv)
    qdd = fns.geodesic_acceleration(q, v)

Every public function here allocates a new graph; nothing is cached.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import casadi as ca
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from geosyn.core import InvalidArgument

__all__ = [
    "SUPPORTED_JOINT_TYPES",
    "DynamicsFunctions",
    "SXLike",
    "aba",
    "bias",
    "count_nodes",
    "crba",
    "dynamics_functions",
    "frame_jacobian",
    "frame_placement",
    "joint_placements",
    "rnea",
]

# A scalar while the graph is built: a Python float (a constant that can still be folded)
# or a 1x1 SX expression.
_Scalar = float | ca.SX
_Vec3 = tuple[_Scalar, _Scalar, _Scalar]
_Mat3 = tuple[_Vec3, _Vec3, _Vec3]  # rows
_Motion = tuple[_Vec3, _Vec3]  # (linear, angular)
_Force = tuple[_Vec3, _Vec3]  # (force, torque)

SXLike = ca.SX | npt.ArrayLike
"""An SX column vector, or numbers (folded into the graph as constants)."""

_ALIGNED_AXES: dict[str, tuple[bool, tuple[float, float, float]]] = {
    "JointModelRX": (False, (1.0, 0.0, 0.0)),
    "JointModelRY": (False, (0.0, 1.0, 0.0)),
    "JointModelRZ": (False, (0.0, 0.0, 1.0)),
    "JointModelPX": (True, (1.0, 0.0, 0.0)),
    "JointModelPY": (True, (0.0, 1.0, 0.0)),
    "JointModelPZ": (True, (0.0, 0.0, 1.0)),
}
_UNALIGNED = {"JointModelRevoluteUnaligned": False, "JointModelPrismaticUnaligned": True}
SUPPORTED_JOINT_TYPES = tuple(_ALIGNED_AXES) + tuple(_UNALIGNED)
"""Pinocchio joint short names the symbolic algorithms accept."""

_SNAP_TOL = 1e-14
_REFERENCES = ("world_aligned", "local")

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
    return ((0.0, -p[2], p[1]), (p[2], 0.0, -p[0]), (-p[1], p[0], 0.0))  # type: ignore[operator]


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


# --------------------------------------------------------------------------------------
# The model, read once per call.
# --------------------------------------------------------------------------------------


def _snap(x: float) -> float:
    if abs(x) < _SNAP_TOL:
        return 0.0
    if abs(abs(x) - 1.0) < _SNAP_TOL:
        return math.copysign(1.0, x)
    return float(x)


def _vec(x: np.ndarray, snap: bool = False) -> tuple[float, float, float]:
    f = _snap if snap else float
    return (f(x[0]), f(x[1]), f(x[2]))


def _mat(x: np.ndarray, snap: bool = False) -> _Mat3:
    return (_vec(x[0], snap), _vec(x[1], snap), _vec(x[2], snap))


@dataclass(frozen=True)
class _Joint:
    index: int  # pinocchio joint id (>= 1)
    parent: int  # pinocchio joint id of the parent (0 is the universe)
    idx_v: int
    prismatic: bool
    axis: tuple[float, float, float]  # unit motion axis in the joint frame
    placement: _SE3  # constant placement in the parent joint frame (floats)
    mass: float  # [kg]
    com: tuple[float, float, float]  # center of mass in the joint frame [m]
    inertia_com: _Mat3  # rotational inertia about the com [kg m^2]
    armature: float  # [kg m^2] or [kg]

    def motion_subspace(self, qd: _Scalar) -> _Motion:
        """``S qd`` as a spatial motion in the joint frame."""
        d = _vscale(qd, self.axis)
        return (d, _ZERO3) if self.prismatic else (_ZERO3, d)

    def project(self, f: _Force) -> _Scalar:
        """``S^T f``."""
        return _dot(self.axis, f[0] if self.prismatic else f[1])


class _Model(NamedTuple):
    joints: tuple[_Joint, ...]
    nv: int
    njoints: int


def _parse_model(model: pin.Model) -> _Model:
    if not isinstance(model, pin.Model):
        raise InvalidArgument(f"model: expected a pinocchio.Model, got {type(model).__name__}")
    if model.nq != model.nv:
        raise InvalidArgument(
            f"model: nq ({model.nq}) != nv ({model.nv}); only fixed-base models with "
            f"one-dof joints of types {', '.join(SUPPORTED_JOINT_TYPES)} are supported"
        )
    armature = np.asarray(model.armature, dtype=float).reshape(-1)
    joints = []
    for i in range(1, model.njoints):
        jm = model.joints[i]
        kind = jm.shortname()
        if kind in _ALIGNED_AXES:
            prismatic, axis = _ALIGNED_AXES[kind]
        elif kind in _UNALIGNED:
            prismatic = _UNALIGNED[kind]
            raw = np.asarray(jm.extract().axis, dtype=float)
            if abs(np.linalg.norm(raw) - 1.0) > 1e-9:
                raise InvalidArgument(
                    f"model: joint {i} '{model.names[i]}' ({kind}) has axis {raw.tolist()} "
                    "of norm != 1; a unit axis is required"
                )
            axis = _vec(raw, snap=True)
        else:
            raise InvalidArgument(
                f"model: joint {i} '{model.names[i]}' has type {kind}, which the symbolic "
                f"algorithms do not support; supported: {', '.join(SUPPORTED_JOINT_TYPES)}"
            )
        placement = model.jointPlacements[i]
        inertia = model.inertias[i]
        joints.append(
            _Joint(
                index=i,
                parent=int(model.parents[i]),
                idx_v=int(jm.idx_v),
                prismatic=prismatic,
                axis=axis,
                placement=_SE3(
                    _mat(np.asarray(placement.rotation), snap=True),
                    _vec(np.asarray(placement.translation)),
                ),
                mass=float(inertia.mass),
                com=_vec(np.asarray(inertia.lever)),
                inertia_com=_mat(np.asarray(inertia.inertia)),
                armature=float(armature[jm.idx_v]),
            )
        )
    return _Model(tuple(joints), int(model.nv), int(model.njoints))


def _joint_transform(joint: _Joint, q: _Scalar) -> _SE3:
    """Placement of the joint's moving frame in its resting frame."""
    ax = joint.axis
    if joint.prismatic:
        return _SE3(_IDENTITY, _vscale(q, ax))
    c: _Scalar
    s: _Scalar
    if isinstance(q, float):
        c, s = math.cos(q), math.sin(q)
    else:
        c, s = ca.cos(q), ca.sin(q)
    # Rodrigues: R = a a^T + c (I - a a^T) + s [a]x, folded entry by entry so that an
    # aligned axis gives the familiar 2x2 block with no multiplications.
    k = _skew(ax)
    rows = []
    for i in range(3):
        row = []
        for j in range(3):
            aa = ax[i] * ax[j]
            row.append(_add(_add(_snap(aa), _mul(c, _snap(float(i == j) - aa))), _mul(s, k[i][j])))
        rows.append(tuple(row))
    return _SE3(tuple(rows), _ZERO3)  # type: ignore[arg-type]


def _liMi(joint: _Joint, q: _Scalar) -> tuple[_SE3, _SE3]:
    """(constant placement, joint motion): parent <- joint is their composition."""
    return joint.placement, _joint_transform(joint, q)


def _child_motion(x: tuple[_SE3, _SE3], m: _Motion) -> _Motion:
    return _motion_act_inv(x[1], _motion_act_inv(x[0], m))


def _parent_force(x: tuple[_SE3, _SE3], f: _Force) -> _Force:
    return _force_act(x[0], _force_act(x[1], f))


def _inertia_times(joint: _Joint, m: _Motion) -> _Force:
    """Spatial inertia of the joint's body times a motion, in the joint frame."""
    lin, ang = m
    p = _vscale(joint.mass, _vadd(lin, _cross(ang, joint.com)))
    return p, _vadd(_matvec(joint.inertia_com, ang), _cross(joint.com, p))


# --------------------------------------------------------------------------------------
# Argument handling.
# --------------------------------------------------------------------------------------


def _scalars(x: object, n: int, name: str) -> list[_Scalar]:
    """Elements of an (n,) SX or numeric vector; constant elements become floats."""
    if isinstance(x, ca.MX):
        raise InvalidArgument(f"{name}: MX is not supported, pass an SX expression")
    if not isinstance(x, ca.SX):
        try:
            arr = np.asarray(x, dtype=float)
        except (TypeError, ValueError) as err:
            raise InvalidArgument(
                f"{name}: expected a casadi.SX or a numeric array of shape ({n},), "
                f"got {type(x).__name__}"
            ) from err
        if arr.shape not in ((n,), (n, 1)):
            raise InvalidArgument(f"{name}: expected shape ({n},), got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise InvalidArgument(f"{name}: must be finite, got {arr.reshape(-1).tolist()}")
        return [float(e) for e in arr.reshape(-1)]
    if x.shape not in ((n, 1), (1, n)):
        raise InvalidArgument(f"{name}: expected an SX of shape ({n}, 1), got {x.shape}")
    x = ca.densify(x)
    out: list[_Scalar] = []
    for k in range(n):
        e = x[k]
        out.append(float(e) if e.is_constant() else e)
    return out


def _to_sx(rows: Sequence[Sequence[_Scalar]]) -> ca.SX:
    """A dense SX matrix from nested lists of scalars."""
    out = ca.SX.zeros(len(rows), len(rows[0]))
    for i, row in enumerate(rows):
        for j, e in enumerate(row):
            if not (isinstance(e, float) and e == 0.0):
                out[i, j] = e
    return out


def _to_sx_column(x: Sequence[_Scalar]) -> ca.SX:
    return _to_sx([[e] for e in x])


def _to_sx_se3(x: _SE3) -> tuple[ca.SX, ca.SX]:
    return _to_sx(x.rotation), _to_sx_column(x.translation)


def _check_frame(model: pin.Model, frame_id: int) -> int:
    if isinstance(frame_id, bool) or not isinstance(frame_id, (int, np.integer)):
        raise InvalidArgument(
            f"frame_id: expected an int, got {type(frame_id).__name__}; "
            "use model.getFrameId(name) to look a frame up by name"
        )
    if not 0 <= frame_id < model.nframes:
        raise InvalidArgument(
            f"frame_id: {frame_id} is out of range; the model has {model.nframes} frames"
        )
    return int(frame_id)


# --------------------------------------------------------------------------------------
# Kinematics.
# --------------------------------------------------------------------------------------


def _forward_placements(m: _Model, qs: list[_Scalar]) -> list[_SE3]:
    oMi = [_SE3_IDENTITY] * m.njoints
    for j in m.joints:
        x0, xj = _liMi(j, qs[j.idx_v])
        oMi[j.index] = _se3_compose(_se3_compose(oMi[j.parent], x0), xj)
    return oMi


def _placements_to(m: _Model, qs: list[_Scalar], target: int) -> list[_SE3]:
    """World placements of ``target`` and its ancestors only (others left at identity)."""
    by_index = {j.index: j for j in m.joints}
    chain = []
    i = target
    while i != 0:
        chain.append(by_index[i])
        i = by_index[i].parent
    oMi = [_SE3_IDENTITY] * m.njoints
    for j in reversed(chain):
        x0, xj = _liMi(j, qs[j.idx_v])
        oMi[j.index] = _se3_compose(_se3_compose(oMi[j.parent], x0), xj)
    return oMi


def joint_placements(model: pin.Model, q: SXLike) -> list[tuple[ca.SX, ca.SX]]:
    """World placements of all joint frames, like Pinocchio's ``data.oMi``.

    Args:
        model: Pinocchio model (fixed base, supported joint types only).
        q: (nq,) joint positions [rad or m], SX or numeric.

    Returns:
        ``njoints`` pairs ``(R, p)``: (3, 3) SX rotation and (3, 1) SX position [m] of
        each joint frame in the world, index 0 being the universe (identity).

    Raises:
        InvalidArgument: unsupported model or wrong shape of ``q``.
    """
    m = _parse_model(model)
    qs = _scalars(q, model.nq, "q")
    return [_to_sx_se3(x) for x in _forward_placements(m, qs)]


def _frame_placement(model: pin.Model, m: _Model, qs: list[_Scalar], frame_id: int) -> _SE3:
    frame = model.frames[frame_id]
    parent = int(frame.parentJoint)
    oMi = _placements_to(m, qs, parent)[parent]
    fp = frame.placement
    local = _SE3(_mat(np.asarray(fp.rotation), snap=True), _vec(np.asarray(fp.translation)))
    return _se3_compose(oMi, local)


def frame_placement(model: pin.Model, q: SXLike, frame_id: int) -> tuple[ca.SX, ca.SX]:
    """World placement of a frame, like Pinocchio's ``data.oMf[frame_id]``.

    Args:
        model: Pinocchio model (fixed base, supported joint types only).
        q: (nq,) joint positions [rad or m], SX or numeric.
        frame_id: index into ``model.frames`` (see ``model.getFrameId(name)``).

    Returns:
        ``(R, p)``: (3, 3) SX rotation and (3, 1) SX position [m] of the frame in the world.

    Raises:
        InvalidArgument: unsupported model, wrong shape of ``q`` or unknown ``frame_id``.
    """
    m = _parse_model(model)
    frame_id = _check_frame(model, frame_id)
    qs = _scalars(q, model.nq, "q")
    return _to_sx_se3(_frame_placement(model, m, qs, frame_id))


def frame_jacobian(
    model: pin.Model, q: SXLike, frame_id: int, reference: str = "world_aligned"
) -> ca.SX:
    """Geometric Jacobian of a frame.

    With ``reference="world_aligned"`` the rows are the velocity of the frame origin and
    the angular velocity, both in world axes (Pinocchio's ``LOCAL_WORLD_ALIGNED``); with
    ``reference="local"`` both in the frame's own axes (Pinocchio's ``LOCAL``):

    .. math::
        \\begin{bmatrix} \\dot p \\\\ \\omega \\end{bmatrix} = J(q)\\, \\dot q

    Args:
        model: Pinocchio model (fixed base, supported joint types only).
        q: (nq,) joint positions [rad or m], SX or numeric.
        frame_id: index into ``model.frames``.
        reference: ``"world_aligned"`` or ``"local"``.

    Returns:
        (6, nv) SX Jacobian, linear rows [m/rad or 1] first, then angular [1 or rad/m].

    Raises:
        InvalidArgument: unsupported model, wrong shape of ``q``, unknown ``frame_id`` or
            ``reference``.
    """
    if reference not in _REFERENCES:
        raise InvalidArgument(
            f"reference: {reference!r} is not supported; allowed: {', '.join(_REFERENCES)}"
        )
    m = _parse_model(model)
    frame_id = _check_frame(model, frame_id)
    qs = _scalars(q, model.nq, "q")
    parent = int(model.frames[frame_id].parentJoint)
    oMi = _placements_to(m, qs, parent)
    oMf = _frame_placement(model, m, qs, frame_id)
    cols: list[list[_Scalar]] = [[0.0] * 6 for _ in range(m.nv)]
    by_index = {j.index: j for j in m.joints}
    i = parent
    while i != 0:
        j = by_index[i]
        axis = _matvec(oMi[i].rotation, j.axis)
        if j.prismatic:
            lin, ang = axis, _ZERO3
        else:
            lin, ang = _cross(axis, _vsub(oMf.translation, oMi[i].translation)), axis
        if reference == "local":
            lin = _matTvec(oMf.rotation, lin)
            ang = _matTvec(oMf.rotation, ang)
        cols[j.idx_v] = [*lin, *ang]
        i = j.parent
    return _to_sx([[cols[c][r] for c in range(m.nv)] for r in range(6)])


# --------------------------------------------------------------------------------------
# Dynamics.
# --------------------------------------------------------------------------------------


def _gravity(gravity: SXLike) -> _Vec3:
    g = _scalars(gravity, 3, "gravity")
    return (g[0], g[1], g[2])


def _rnea(m: _Model, qs, vs, accs, g: _Vec3) -> list[_Scalar]:
    n = m.njoints
    vel: list[_Motion] = [(_ZERO3, _ZERO3)] * n
    # Gravity enters as an upward acceleration of the base (Pinocchio's a_gf[0] = -g).
    acc: list[_Motion] = [(_vscale(-1.0, g), _ZERO3)] * n
    force: list[_Force] = [(_ZERO3, _ZERO3)] * n
    xs = {}
    for j in m.joints:
        k = j.idx_v
        x = _liMi(j, qs[k])
        xs[j.index] = x
        vj = j.motion_subspace(vs[k])
        v_parent = _child_motion(x, vel[j.parent])
        vel[j.index] = _madd6(v_parent, vj)
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
    m = _parse_model(model)
    tau = _rnea(
        m,
        _scalars(q, model.nq, "q"),
        _scalars(v, model.nv, "v"),
        _scalars(a, model.nv, "a"),
        _gravity(gravity),
    )
    return _to_sx_column(tau)


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
            f: _Force = (_vscale(mass, ax), _cross(h, ax))  # type: ignore[arg-type]
        else:
            f = (_cross(ax, h), _matvec(io, ax))  # type: ignore[arg-type]
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

    def __add__(self, other: object) -> _Articulated:  # type: ignore[override]
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
    xs = {}
    vel: list[_Motion] = [(_ZERO3, _ZERO3)] * n
    bias_acc: list[_Motion] = [(_ZERO3, _ZERO3)] * n
    inertia: dict[int, _Articulated] = {}
    pa: dict[int, _Force] = {}
    for j in m.joints:
        k = j.idx_v
        x = _liMi(j, qs[k])
        xs[j.index] = x
        vj = j.motion_subspace(vs[k])
        v_parent = _child_motion(x, vel[j.parent])
        vel[j.index] = _madd6(v_parent, vj)
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
    m = _parse_model(model)
    qdd = _aba(
        m,
        _scalars(q, model.nq, "q"),
        _scalars(v, model.nv, "v"),
        _scalars(tau, model.nv, "tau"),
        _gravity(gravity),
    )
    return _to_sx_column(qdd)


def count_nodes(*exprs: ca.SX) -> int:
    """Size of the graph of SX expressions: ``casadi.Function(...).n_nodes()``.

    Counts the symbolic inputs, constants and operations reachable from ``exprs``, without
    common-subexpression elimination beyond the sharing already in the graph.

    Args:
        *exprs: SX expressions of any shape.

    Returns:
        Number of nodes.
    """
    leaves = ca.symvar(ca.veccat(*[ca.vec(e) for e in exprs]))
    return int(ca.Function("count_nodes", leaves, list(exprs)).n_nodes())


class DynamicsFunctions(NamedTuple):
    """Compiled-on-demand CasADi functions of one model (SX graphs, built once).

    Each is a ``casadi.Function``; call it with numpy arrays, it returns ``casadi.DM``
    (see :mod:`geosyn.core.codegen` for C code generation).
    """

    M: ca.Function  # q (nq,) -> M (nv, nv) mass matrix
    rnea: ca.Function  # q, v, a -> tau (nv,) inverse dynamics
    bias: ca.Function  # q, v -> h (nv,) C(q, v) v + g(q)
    aba: ca.Function  # q, v, tau -> a (nv,) forward dynamics
    geodesic_acceleration: ca.Function  # q, v -> a (nv,), aba with zero gravity and torque


def dynamics_functions(model: pin.Model, gravity: npt.ArrayLike) -> DynamicsFunctions:
    """Build the CasADi functions of a model's dynamics (allocates; call once).

    Args:
        model: Pinocchio model (fixed base, supported joint types only).
        gravity: (3,) gravity acceleration in the world frame [m/s^2], numeric; it is
            embedded as a constant in ``rnea``, ``bias`` and ``aba``.

    Returns:
        The functions ``M``, ``rnea``, ``bias``, ``aba`` and ``geodesic_acceleration``,
        each built with common-subexpression elimination.

    Raises:
        InvalidArgument: unsupported model, or ``gravity`` not a finite numeric (3,) array.
    """
    if isinstance(gravity, (ca.SX, ca.MX)):
        raise InvalidArgument("gravity: expected a numeric (3,) array, got a symbolic one")
    g = np.array(_gravity(gravity), dtype=float)  # validated: numeric, finite, (3,)
    _parse_model(model)
    nq, nv = model.nq, model.nv
    q = ca.SX.sym("q", nq)
    v = ca.SX.sym("v", nv)
    a = ca.SX.sym("a", nv)
    tau = ca.SX.sym("tau", nv)
    opts = {"cse": True}
    return DynamicsFunctions(
        M=ca.Function("M", [q], [crba(model, q)], ["q"], ["M"], opts),
        rnea=ca.Function(
            "rnea", [q, v, a], [rnea(model, q, v, a, g)], ["q", "v", "a"], ["tau"], opts
        ),
        bias=ca.Function("bias", [q, v], [bias(model, q, v, g)], ["q", "v"], ["h"], opts),
        aba=ca.Function(
            "aba", [q, v, tau], [aba(model, q, v, tau, g)], ["q", "v", "tau"], ["a"], opts
        ),
        geodesic_acceleration=ca.Function(
            "geodesic_acceleration",
            [q, v],
            [aba(model, q, v, np.zeros(nv), np.zeros(3))],
            ["q", "v"],
            ["a"],
            opts,
        ),
    )
