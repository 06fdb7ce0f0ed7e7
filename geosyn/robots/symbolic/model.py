"""The Pinocchio model read once per call, and argument conversion to folded scalars."""

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
from geosyn.core.validation import check_int
from geosyn.robots.floating import is_floating
from geosyn.robots.symbolic.algebra import (
    _IDENTITY,
    _SE3,
    _ZERO3,
    _add,
    _cross,
    _dot,
    _Force,
    _force_act,
    _Mat3,
    _matvec,
    _Motion,
    _motion_act_inv,
    _mul,
    _Scalar,
    _skew,
    _vadd,
    _vscale,
)

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
        floating = " (a floating base: its free flyer lives on SE(3))" if is_floating(model) else ""
        raise InvalidArgument(
            f"model: nq ({model.nq}) != nv ({model.nv}){floating}; only fixed-base models with "
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
    """``frame_id`` as an index into ``model.frames`` (see ``model.getFrameId(name)``)."""
    return check_int(frame_id, "frame_id", low=0, high=model.nframes - 1)
