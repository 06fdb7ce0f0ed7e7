"""The robot file's own collision geometry as MuJoCo geoms of geosyn's rebuilt model.

`geosyn.sim.build_scene` rebuilds the robot from its Pinocchio model (`Robot.mjcf`), whose
only geoms are the collision capsules. With ``contact=True`` the obstacles must collide
with the robot as its file describes it, as the planner and the exact clearance see it: so
the collision objects of the file (`geosyn.robots.collision_geometry`: URDF meshes and
primitives, MJCF geoms) are added to the bodies of the joints that carry them, massless
and invisible (MuJoCo collides a mesh as its convex hull, as coal does in
`geosyn.world.exact_clearance`), and they, not the capsules, collide. Objects fixed to
the base are left out: they sit in the world body with the obstacles, and MuJoCo does not
collide a body with itself. A robot without file geometry on a moving link (built in
code) collides its capsules, and `CollisionGeoms.note` says so.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from xml.sax.saxutils import quoteattr

import numpy as np

from geosyn.robots.collision_geometry import CollisionObject, collision_objects
from geosyn.robots.errors import RobotFileError
from geosyn.robots.mjcf import mjcf_number as _f
from geosyn.robots.mjcf import mjcf_vector as _vec
from geosyn.robots.robot import Robot
from geosyn.world.pose import quaternion_wxyz

__all__ = ["COLLISION_PREFIX", "CollisionGeoms", "collision_geoms"]

COLLISION_PREFIX = "file_collision"
"""Name prefix of the geoms (and meshes) made from the file's collision objects."""


@dataclass(frozen=True)
class CollisionGeoms:
    """MJCF text of a robot file's collision objects.

    Attributes:
        asset: ``<asset>`` element with the meshes ("" if none).
        bodies: geoms to add to the body of each joint, keyed by Pinocchio joint name.
        note: what collides: the file's objects, or the capsules and why.
    """

    asset: str = ""
    bodies: dict[str, str] = field(default_factory=dict)
    note: str = ""

    @property
    def from_file(self) -> bool:
        """The robot's file geometry is there on a moving link (else the capsules collide)."""
        return bool(self.bodies)


def _shape(i: int, o: CollisionObject) -> tuple[str, str]:
    """(asset element, geom attributes giving the shape) of object ``o``."""
    s = np.asarray(o.size, dtype=np.float64)
    if o.kind == "mesh":
        name = f"{COLLISION_PREFIX}{i}"
        mesh = (
            f"<mesh name={quoteattr(name)} vertex={quoteattr(_vec(o.vertices.reshape(-1)))}"
            f" face={quoteattr(' '.join(str(int(k)) for k in o.faces.reshape(-1)))}/>"
        )
        return mesh, f'type="mesh" mesh={quoteattr(name)}'
    if o.kind in ("box", "ellipsoid"):
        return "", f'type="{o.kind}" size="{_vec(s)}"'
    if o.kind == "sphere":
        return "", f'type="sphere" size="{_f(s[0])}"'
    return "", f'type="{o.kind}" size="{_f(s[0])} {_f(s[1])}"'  # capsule, cylinder: r, half z


def collision_geoms(robot: Robot) -> CollisionGeoms:
    """The collision objects of ``robot``'s file as MJCF (see the module doc); the
    capsules' note when the robot has no readable file geometry."""
    try:
        objects = collision_objects(robot)
    except RobotFileError as err:
        return CollisionGeoms(note=f"the collision capsules collide ({err})")
    assets: list[str] = []
    bodies: dict[str, str] = {}
    for i, o in enumerate(objects):
        if o.joint == "universe":
            continue  # fixed to the base (see the module doc)
        asset, shape = _shape(i, o)
        if asset:
            assets.append(asset)
        T = np.asarray(o.placement, dtype=np.float64)
        geom = (
            f'<geom name={quoteattr(f"{COLLISION_PREFIX}{i}")} {shape} pos="{_vec(T[:3, 3])}"'
            f' quat="{_vec(quaternion_wxyz(T[:3, :3]))}" contype="0" conaffinity="0"'
            ' group="3" rgba="0.5 0.5 0.5 0" mass="0"/>'
        )
        bodies[o.joint] = bodies.get(o.joint, "") + geom
    if not bodies:
        return CollisionGeoms(
            note="the collision capsules collide (no file geometry on a moving link)"
        )
    note = f"the file's collision objects on {len(bodies)} joints collide (meshes as convex hulls)"
    asset_xml = f"  <asset>{''.join(assets)}</asset>" if assets else ""
    return CollisionGeoms(asset_xml, bodies, note)
