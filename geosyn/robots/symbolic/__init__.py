"""Symbolic rigid-body algorithms in CasADi SX, built from a ``pinocchio.Model``.

Pinocchio's PyPI wheel ships without ``pinocchio.casadi``, so geosyn keeps its own small
symbolic versions of the algorithms it needs: inverse dynamics (RNEA), the joint-space
mass matrix (CRBA), forward dynamics (ABA), frame placements and frame Jacobians. Each is
a pure function of the model and CasADi ``SX`` expressions and returns ``SX``; the results
match Pinocchio's numerical algorithms to round-off (the tests compare to 1e-12 relative).

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

Modules: `algebra` (folded scalar, 3-vector and spatial algebra), `model` (the model read
once per call, argument conversion), `kinematics` (placements, frame Jacobians),
`dynamics` (RNEA, CRBA, ABA), `functions` (`dynamics_functions`, `count_nodes`).

Typical use (build once, call often)::

    fns = dynamics_functions(model, gravity=np.array([0.0, 0.0, -9.81]))
    M = fns.M(q)                       # casadi.DM (nv, nv)
    qdd = fns.geodesic_acceleration(q, v)

Every public function here allocates a new graph; nothing is cached. The compiled-code
cache (`geosyn.core.codegen`) is keyed by the generated source, so a change to the order
of operations here forces a recompilation of every cached function.
"""

from geosyn.robots.symbolic.dynamics import aba, bias, crba, rnea
from geosyn.robots.symbolic.functions import DynamicsFunctions, count_nodes, dynamics_functions
from geosyn.robots.symbolic.kinematics import frame_jacobian, frame_placement, joint_placements
from geosyn.robots.symbolic.model import SUPPORTED_JOINT_TYPES, SXLike

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
