"""Symbolic kinematics: joint and frame placements, frame Jacobians."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin

from geosyn.core.validation import check_choice
from geosyn.robots.symbolic.algebra import (
    _SE3,
    _SE3_IDENTITY,
    _ZERO3,
    _cross,
    _matTvec,
    _matvec,
    _Scalar,
    _se3_compose,
    _vsub,
)
from geosyn.robots.symbolic.model import (
    SXLike,
    _check_frame,
    _liMi,
    _mat,
    _Model,
    _parse_model,
    _scalars,
    _to_sx,
    _to_sx_se3,
    _vec,
)

_REFERENCES = ("world_aligned", "local")


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
    check_choice(reference, _REFERENCES, "reference")
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
