"""A robot's own collision geometry, read from its file: meshes and primitives per link.

A URDF's ``<collision>`` elements are read by Pinocchio (``buildGeomFromUrdf``: meshes as
coal BVH models, primitives as coal shapes); an MJCF's collision geoms (``contype`` or
``conaffinity`` non-zero) from MuJoCo's compile of the file (meshes as MuJoCo collides
them, their convex hull; boxes, spheres, capsules, cylinders, ellipsoids). Each object is
placed in the frame of the `Robot`'s joint that carries it (found through its link's
frame, so locked joints such as the Panda's fingers are held where the robot locked them).

Used by `geosyn.robots.collision_spheres` (spheres fitted to it) and by the exact
verification of plans (`geosyn.world.exact`, coal distances). No geometry is simplified
here: a primitive keeps its kind and sizes, a mesh its vertices and faces.
"""

from __future__ import annotations

import hashlib
import weakref
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from geosyn.robots.errors import RobotFileError
from geosyn.robots.robot import Robot

__all__ = [
    "KINDS",
    "CollisionObject",
    "collision_objects",
    "edge_cuts",
    "file_bvh",
    "geometry_digest",
    "surface_points",
    "surface_triangles",
]

KINDS = ("mesh", "box", "sphere", "capsule", "cylinder", "ellipsoid")
"""Kinds of `CollisionObject`."""


@dataclass(frozen=True, eq=False)
class CollisionObject:
    """One collision body of a robot file, rigidly attached to a joint.

    Attributes:
        name: the file's name of the object (URDF link + index, MJCF geom name or index).
        joint: name of the `Robot` joint carrying it (``"universe"``: fixed to the base).
        link: the link (URDF) or body (MJCF) it belongs to.
        placement: (4, 4) pose of the object's frame in the joint frame [m].
        kind: one of `KINDS`.
        size: the primitive's sizes [m]: box half-extents (3,), sphere radius (1,),
            capsule and cylinder (radius, half-length along z), ellipsoid semi-axes (3,);
            empty for a mesh.
        vertices: (V, 3) a mesh's vertices in the object's frame [m] (scale applied);
            (0, 3) for a primitive.
        faces: (F, 3) a mesh's triangles (vertex indices); (0, 3) for a primitive.
    """

    name: str
    joint: str
    link: str
    placement: np.ndarray
    kind: str
    size: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray


def _frame_pose(robot: Robot, link: str, source: str) -> tuple[str, pin.SE3]:
    """(joint name, joint-from-link pose) of ``link``'s body frame in ``robot.model`` (a
    joint of the same name has a frame too: the Unitree Z1's ``gripperStator``)."""
    model = robot.model
    if not model.existFrame(link, pin.FrameType.BODY):
        raise RobotFileError(
            f"collision geometry of {source}: link {link!r} is not a frame of robot "
            f"{robot.name!r}", source,
        )  # fmt: skip
    frame = model.frames[model.getFrameId(link, pin.FrameType.BODY)]
    return str(model.names[frame.parentJoint]), frame.placement


def _from_urdf(robot: Robot, path: Path) -> list[CollisionObject]:
    import coal

    share = [str(p) for p in path.parents if p.name == "share"] + [str(path.parent)]
    full = pin.buildModelFromUrdf(str(path))
    try:
        gm = pin.buildGeomFromUrdf(full, str(path), pin.GeometryType.COLLISION, package_dirs=share)
    except (RuntimeError, ValueError) as err:
        raise RobotFileError(
            f"could not read the collision geometry of {path}: {err}", path
        ) from err
    out = []
    for go in gm.geometryObjects:
        link = full.frames[go.parentFrame].name
        joint, jMl = _frame_pose(robot, link, str(path))
        # the object's pose relative to its link's frame, then in the robot's joint frame
        lMo = full.frames[go.parentFrame].placement.inverse() * go.placement
        g = go.geometry
        verts, faces, size = np.zeros((0, 3)), np.zeros((0, 3), dtype=int), np.zeros(0)
        if isinstance(g, coal.BVHModelBase):
            kind = "mesh"
            verts = np.array(g.vertices(), dtype=np.float64)
            faces = np.array([[t[0], t[1], t[2]] for t in (g.tri_indices(i) for i in range(g.num_tris))], dtype=int)  # fmt: skip
        elif isinstance(g, coal.Box):
            kind, size = "box", np.array(g.halfSide, dtype=np.float64)
        elif isinstance(g, coal.Sphere):
            kind, size = "sphere", np.array([g.radius])
        elif isinstance(g, coal.Capsule):
            kind, size = "capsule", np.array([g.radius, g.halfLength])
        elif isinstance(g, coal.Cylinder):
            kind, size = "cylinder", np.array([g.radius, g.halfLength])
        else:
            raise RobotFileError(
                f"collision geometry {go.name!r} of {path}: {type(g).__name__} is not "
                f"supported; supported: {', '.join(KINDS[:-1])}", path,
            )  # fmt: skip
        out.append(CollisionObject(go.name, joint, link, (jMl * lMo).homogeneous, kind, size,
                                   verts, faces))  # fmt: skip
        if kind == "mesh":
            _FILE_BVH[out[-1]] = g
    return out


#: The coal BVH Pinocchio built for each URDF mesh object while reading the file.
_FILE_BVH: weakref.WeakKeyDictionary[CollisionObject, object] = weakref.WeakKeyDictionary()


def file_bvh(obj: CollisionObject) -> object | None:
    """The coal BVH (its triangles in the object's frame, `CollisionObject.vertices` and
    ``faces``) Pinocchio built for a URDF mesh object when the file was read, or None
    (another kind or file): a caller that needs it need not build it again."""
    return _FILE_BVH.get(obj)


def _from_mjcf(robot: Robot, path: Path) -> list[CollisionObject]:
    import mujoco

    from geosyn.robots.from_mjcf import compile_mjcf

    m = compile_mjcf(path)
    kinds = {
        int(mujoco.mjtGeom.mjGEOM_BOX): "box",
        int(mujoco.mjtGeom.mjGEOM_SPHERE): "sphere",
        int(mujoco.mjtGeom.mjGEOM_CAPSULE): "capsule",
        int(mujoco.mjtGeom.mjGEOM_CYLINDER): "cylinder",
        int(mujoco.mjtGeom.mjGEOM_ELLIPSOID): "ellipsoid",
        int(mujoco.mjtGeom.mjGEOM_MESH): "mesh",
    }
    out = []
    for g in range(m.ngeom):
        if not (m.geom_contype[g] or m.geom_conaffinity[g]) or m.geom_bodyid[g] == 0:
            continue  # visual-only geoms, and the world's own (the scene, not the robot)
        kind = kinds.get(int(m.geom_type[g]))
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}"
        if kind is None:
            raise RobotFileError(
                f"collision geom {name!r} of {path}: type {int(m.geom_type[g])} is not "
                f"supported; supported: {', '.join(KINDS)}", path,
            )  # fmt: skip
        body = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[g]))
        joint, jMb = _frame_pose(robot, body, str(path))
        quat = np.array(m.geom_quat[g], dtype=np.float64)  # w, x, y, z
        bMo = pin.SE3(pin.Quaternion(quat[0], quat[1], quat[2], quat[3]).matrix(),
                      np.array(m.geom_pos[g], dtype=np.float64))  # fmt: skip
        s = np.array(m.geom_size[g], dtype=np.float64)
        verts, faces = np.zeros((0, 3)), np.zeros((0, 3), dtype=int)
        size = {"box": s, "sphere": s[:1], "capsule": s[:2], "cylinder": s[:2],
                "ellipsoid": s, "mesh": np.zeros(0)}[kind]  # fmt: skip
        if kind == "mesh":
            k = int(m.geom_dataid[g])
            a, nv = int(m.mesh_vertadr[k]), int(m.mesh_vertnum[k])
            verts = np.array(m.mesh_vert[a : a + nv], dtype=np.float64)
            fa, nf = int(m.mesh_faceadr[k]), int(m.mesh_facenum[k])
            faces = np.array(m.mesh_face[fa : fa + nf], dtype=int)
        out.append(CollisionObject(name, joint, body, (jMb * bMo).homogeneous, kind,
                                   size, verts, faces))  # fmt: skip
    return out


def collision_objects(robot: Robot) -> tuple[CollisionObject, ...]:
    """The collision objects of ``robot``'s file (see the module docstring).

    Args:
        robot: a robot loaded from a URDF or MJCF file (``robot.source_file``).

    Returns:
        The objects, in file order; objects on locked joints move with the joint that
        carries them in ``robot.model``. Read once per robot object and file version;
        their arrays are read-only (shared).

    Raises:
        RobotFileError: no source file, an unreadable file or mesh, a link that is not a
            frame of the robot, or an unsupported geometry type (named).
    """
    if robot.source_file is None:
        raise RobotFileError(
            f"robot {robot.name!r} was built in code and has no file with collision "
            "geometry; pass collision spheres explicitly"
        )
    path = Path(robot.source_file)
    try:
        stat = path.stat()
        stamp: tuple[object, ...] = (str(path), stat.st_mtime_ns, stat.st_size)
    except OSError:
        stamp = (str(path),)  # the read below names the problem
    hit = _READ.get(id(robot))
    if hit is not None and hit[0]() is robot and hit[1] == stamp:
        return hit[2]
    objects = _from_urdf(robot, path) if path.suffix.lower() == ".urdf" else _from_mjcf(robot, path)
    if not objects:
        raise RobotFileError(f"robot file {path} has no collision geometry", path)
    for o in objects:  # shared by every caller from now on
        for arr in (o.placement, o.size, o.vertices, o.faces):
            arr.setflags(write=False)
    key = id(robot)
    _READ[key] = (weakref.ref(robot, lambda _: _READ.pop(key, None)), stamp, tuple(objects))
    return _READ[key][2]


#: The objects read per robot object (while it lives) and file stamp: the scene's contact
#: geoms, the exact checks and the sphere fits of one robot read its meshes once.
_READ: dict[int, tuple[weakref.ref[Robot], tuple[object, ...], tuple[CollisionObject, ...]]] = {}


def geometry_digest(objects: tuple[CollisionObject, ...]) -> str:
    """sha256 (hex) of the objects' joints, placements, kinds, sizes and meshes."""
    h = hashlib.sha256()
    for o in objects:
        h.update(f"{o.joint}|{o.kind}|".encode())
        for arr in (o.placement, o.size, o.vertices):
            h.update(np.ascontiguousarray(np.round(arr, 12), dtype=np.float64).tobytes())
        h.update(np.ascontiguousarray(o.faces, dtype=np.int64).tobytes())
    return h.hexdigest()


def edge_cuts(tris: np.ndarray, spacing: float) -> np.ndarray:
    """(F,) int: the cuts ``k`` per edge that make a barycentric grid on each triangle of
    ``tris`` (F, 3, 3) [m] have edges <= ``spacing`` [m] (its longest edge / spacing,
    rounded up, at least 1)."""
    tris = np.asarray(tris, dtype=np.float64)
    longest = np.linalg.norm(tris - np.roll(tris, 1, axis=1), axis=2).max(axis=1)
    return np.maximum(1, np.ceil(longest / spacing).astype(np.int64))


def _triangle_samples(tris: np.ndarray, spacing: float) -> np.ndarray:
    """(P, 3) points on the triangles ``tris`` (F, 3, 3), each on a barycentric grid with
    edges <= ``spacing`` (`edge_cuts`), for all the triangles of one ``k`` at once."""
    tris = np.asarray(tris, dtype=np.float64)
    ks = edge_cuts(tris, spacing)
    out = []
    for k in np.unique(ks):
        t = tris[ks == k]
        i, j = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
        keep = i + j <= k
        a, b = (i[keep] / k)[None, :, None], (j[keep] / k)[None, :, None]
        t0 = t[:, 0][:, None, :]
        out.append(
            (
                t0 + a * (t[:, 1] - t[:, 0])[:, None, :] + b * (t[:, 2] - t[:, 0])[:, None, :]
            ).reshape(-1, 3)
        )
    return np.concatenate(out) if out else np.zeros((0, 3))


def _primitive_mesh(obj: CollisionObject) -> tuple[np.ndarray, np.ndarray]:
    """A triangulated surface that encloses the primitive (vertices on or outside it)."""
    import trimesh

    s = obj.size
    if obj.kind == "box":
        mesh = trimesh.creation.box(extents=2.0 * s)
    elif obj.kind == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=s[0])
    elif obj.kind == "ellipsoid":
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
        mesh.apply_scale(s)
    elif obj.kind == "capsule":
        mesh = trimesh.creation.capsule(height=2.0 * s[1], radius=s[0], count=[24, 24])
    else:
        mesh = trimesh.creation.cylinder(radius=s[0], height=2.0 * s[1], sections=48)
    # a polyhedron inscribed in a curved surface lies inside it: push its vertices out
    # so that the polyhedron encloses the primitive (chord error of the tessellation)
    v = np.array(mesh.vertices, dtype=np.float64)
    if obj.kind != "box":
        v *= 1.0 / np.cos(np.pi / 24.0)
    return v, np.array(mesh.faces, dtype=int)


def surface_triangles(obj: CollisionObject) -> np.ndarray:
    """(F, 3, 3) the object's surface triangles in its joint frame [m] (a primitive's
    enclosing polyhedron)."""
    verts, faces = (obj.vertices, obj.faces) if obj.kind == "mesh" else _primitive_mesh(obj)
    v = verts @ obj.placement[:3, :3].T + obj.placement[:3, 3]
    return np.asarray(v[faces])


def surface_points(obj: CollisionObject, spacing: float) -> np.ndarray:
    """(P, 3) points on the object's surface in its joint frame [m], every vertex
    included, triangles sampled with edges <= ``spacing`` [m]; a point of the surface is
    within ``spacing / sqrt(3)`` of a sample. A primitive is sampled on a polyhedron
    that encloses it."""
    verts, faces = (obj.vertices, obj.faces) if obj.kind == "mesh" else _primitive_mesh(obj)
    pts = [verts, _triangle_samples(verts[faces], spacing)]
    P = np.unique(np.round(np.vstack(pts), 12), axis=0)
    return P @ obj.placement[:3, :3].T + obj.placement[:3, 3]
