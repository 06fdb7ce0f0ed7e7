"""Linear joint couplings: ``q = S z + c`` onto independent coordinates z.

Robot files couple joints with linear equality constraints: an MJCF joint equality
``joint1 - joint1_0 = a0 + a1 (joint2 - joint2_0)``, an MJCF equality between fixed
tendons (``L1 - L1_0 = a0 + a1 (L2 - L2_0)`` with ``L = sum_k coef_k q_k``), a URDF
``<mimic>`` (``joint = multiplier * leader + offset``). Each is a row of ``A q = b``;
each row names one dependent joint (its pivot: the constrained joint of a joint equality
or mimic, the largest-coefficient joint of a tendon), the other joints are the
independent coordinates z, and

.. math::
    q_D = A_D^{-1} (b - A_I q_I), \\qquad q = S z + c.

The pull-back metric ``G_z = S^T G S`` (`geosyn.metrics.CoupledMetric`) is the kinetic
energy of the coupled robot; its geodesics are the robot's passive constrained motions.
Geodesics and synergies are computed in z; controllers track them in q, lifted by
`Coupling.lift` (arrays) or `geosyn.controllers.CoupledReference` (a reference).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_vector
from geosyn.robots.errors import RobotFileError


class LinearConstraint(NamedTuple):
    """One linear equality ``sum_j coefficients[j] q_j = rhs`` stated by a robot file."""

    name: str  # the file's element, e.g. "equality 'finger_coupling' (joint)"
    coefficients: Mapping[str, float]  # joint name -> coefficient
    rhs: float
    pivot: str  # the joint this row makes dependent


@dataclass(frozen=True)
class Coupling:
    """``q = S z + c``: the joints as an affine function of the independent coordinates.

    Attributes:
        S: (nq, nz) constant map [rad/rad].
        c: (nq,) offset [rad or m].
        joint_names: (nq,) names of q (the robot's joints).
        independent: (nz,) names of z (the independent joints, z_i = q of that joint).
        constraints: descriptions of the rows, as the file states them.
    """

    S: np.ndarray
    c: np.ndarray
    joint_names: tuple[str, ...]
    independent: tuple[str, ...]
    constraints: tuple[str, ...]

    @property
    def nz(self) -> int:
        """Number of independent coordinates."""
        return int(self.S.shape[1])

    def q(self, z: Vector) -> Vector:
        """(nq,) joint positions of the independent coordinates ``z`` (nz,)."""
        return self.S @ check_vector(z, self.nz, "z") + self.c

    def velocity(self, z_dot: Vector) -> Vector:
        """(nq,) joint velocities ``S z_dot`` of independent velocities (nz,) [rad/s]."""
        return self.S @ check_vector(z_dot, self.nz, "z_dot")

    def z(self, q: Vector) -> Vector:
        """(nz,) independent coordinates of joint positions ``q`` (nq,): the independent
        joints' values (q is assumed to satisfy the constraints)."""
        q = check_vector(q, len(self.joint_names), "q")
        return np.array([q[self.joint_names.index(n)] for n in self.independent])

    def lift(
        self, z: np.ndarray, z_dot: np.ndarray, z_ddot: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint trajectories of a trajectory in z (e.g. a geodesic of `CoupledMetric`), for
        a joint-space reference that any controller tracks on the coupled robot.

        Args:
            z, z_dot, z_ddot: (T, nz) positions [rad], velocities [rad/s], accelerations
                [rad/s^2] of the independent coordinates.

        Returns:
            (T, nq) ``S z + c``, ``S z_dot``, ``S z_ddot``.
        """
        arrays = [np.asarray(x, dtype=np.float64) for x in (z, z_dot, z_ddot)]
        for label, x in zip(("z", "z_dot", "z_ddot"), arrays, strict=True):
            if x.ndim != 2 or x.shape[1] != self.nz or x.shape != arrays[0].shape:
                raise InvalidArgument(
                    f"{label} must have shape (T, {self.nz}) like z, got {x.shape}"
                )
        return arrays[0] @ self.S.T + self.c, arrays[1] @ self.S.T, arrays[2] @ self.S.T

    def residual(self, q: Vector) -> float:
        """Largest violation of the constraints at ``q`` (0 on the coupled manifold)."""
        q = check_vector(q, len(self.joint_names), "q")
        return float(np.abs(self.q(self.z(q)) - q).max())


def linear_coupling(
    joint_names: Sequence[str], constraints: Sequence[LinearConstraint]
) -> Coupling:
    """The coupling ``q = S z + c`` of linear equality constraints.

    Args:
        joint_names: (nq,) joint names, in configuration order.
        constraints: the rows; each names a distinct pivot joint.

    Returns:
        The coupling.

    Raises:
        RobotFileError: a row names an unknown joint, two rows the same pivot, or the
            rows are dependent or conflicting (singular ``A_D``); names the constraint.
    """
    names = list(joint_names)
    n, r = len(names), len(constraints)
    A, b = np.zeros((r, n)), np.zeros(r)
    pivots: list[int] = []
    for i, con in enumerate(constraints):
        for joint, coef in con.coefficients.items():
            if joint not in names:
                raise RobotFileError(
                    f"{con.name} names joint {joint!r}, which is not a robot joint"
                )
            A[i, names.index(joint)] += float(coef)
        b[i] = float(con.rhs)
        p = names.index(con.pivot)
        if p in pivots:
            raise RobotFileError(
                f"{con.name} makes joint {con.pivot!r} dependent a second time; geosyn"
                " supports one constraint per dependent joint"
            )
        pivots.append(p)
    free = [j for j in range(n) if j not in pivots]
    A_D = A[:, pivots]
    if r and np.linalg.cond(A_D) > 1e12:
        raise RobotFileError(
            f"the couplings {[c.name for c in constraints]} are dependent or conflicting"
        )
    S, c = np.zeros((n, len(free))), np.zeros(n)
    S[free, range(len(free))] = 1.0
    if r:
        S[pivots] = -np.linalg.solve(A_D, A[:, free])
        c[pivots] = np.linalg.solve(A_D, b)
    return Coupling(
        S=S,
        c=c,
        joint_names=tuple(names),
        independent=tuple(names[j] for j in free),
        constraints=tuple(con.name for con in constraints),
    )
