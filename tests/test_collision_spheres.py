"""Collision spheres fitted to the robot's own collision geometry (issue 22).

References: Pinocchio's own collision model of the Panda URDF (coal meshes placed by
``updateGeometryPlacements``) and MuJoCo's own compile of an MJCF (``geom_xpos``,
``geom_xmat``); surface points drawn by trimesh (seeded), independently of the fit.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
import trimesh

from geosyn.robots import load_robot
from geosyn.robots.collision_spheres import SphereModel, _reach, file_spheres, subdivide
from geosyn.robots.files import example_robot_data_dir
from geosyn.robots.mesh_inside import SolidTest
from geosyn.robots.robot import Robot


def _world_spheres(
    robot: Robot, model: SphereModel, q: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    C = []
    for s in model.spheres:
        M = data.oMi[robot.joint_id(s.joint)]
        C.append(M.rotation @ np.asarray(s.center) + M.translation)
    return np.array(C), np.array([s.radius for s in model.spheres])


def _pinocchio_collision_model(robot: Robot) -> tuple[pin.Model, pin.GeometryModel]:
    """Pinocchio's own model and collision model of ``robot``'s URDF (all its joints)."""
    share = str(example_robot_data_dir().parents[1])
    full = pin.buildModelFromUrdf(robot.source_file)
    gm = pin.buildGeomFromUrdf(full, robot.source_file, pin.GeometryType.COLLISION,
                               package_dirs=[share])  # fmt: skip
    return full, gm


def _full_q(robot: Robot, full: pin.Model, q: np.ndarray) -> np.ndarray:
    """``q`` (n,) [rad] of ``robot`` as a configuration of the full model (the rest
    neutral), by joint name."""
    qf = pin.neutral(full)
    for i, name in enumerate(robot.joint_names):
        qf[full.joints[full.getJointId(name)].idx_q] = q[i]
    return qf


def _depth_inside(points: np.ndarray, C: np.ndarray, R: np.ndarray) -> np.ndarray:
    """(P,) how deep each point lies inside its deepest sphere [m] (negative: outside)."""
    d = np.linalg.norm(points[:, None, :] - C[None], axis=2)
    return np.asarray((R[None] - d).max(axis=1))


@pytest.fixture(scope="module")
def panda_spheres(panda: Robot) -> SphereModel:
    return file_spheres(panda)


def test_panda_spheres_cover_every_urdf_mesh_point(
    panda: Robot, panda_spheres: SphereModel
) -> None:
    """Every vertex of every URDF collision mesh (and 2,000 seeded surface samples per
    object, boxes included) lies >= margin inside a sphere, at 3 seeded configurations."""
    full, gm = _pinocchio_collision_model(panda)
    fdata, gdata = full.createData(), pin.GeometryData(gm)
    rng = np.random.default_rng(3)
    margin = panda_spheres.margin
    assert len(panda_spheres.spheres) >= 11  # at least one per link with geometry
    for _ in range(3):
        q = panda.random_q(rng)
        pin.updateGeometryPlacements(full, fdata, gm, gdata, _full_q(panda, full, q))
        C, R = _world_spheres(panda, panda_spheres, q)
        for k, go in enumerate(gm.geometryObjects):
            g = go.geometry
            if hasattr(g, "vertices"):
                verts = np.asarray(g.vertices())
                faces = np.array([[t[0], t[1], t[2]] for t in (g.tri_indices(i) for i in range(g.num_tris))])  # fmt: skip
                mesh = trimesh.Trimesh(verts, faces, process=False)
            else:  # a box primitive (the fingers)
                mesh = trimesh.creation.box(extents=2.0 * np.asarray(g.halfSide))
            pts, _ = trimesh.sample.sample_surface(mesh, 2000, seed=k)
            local = np.vstack([mesh.vertices, pts])
            M = gdata.oMg[k]
            world = local @ M.rotation.T + M.translation
            depth = _depth_inside(world, C, R)
            assert depth.min() >= margin - 1e-9, (go.name, depth.min())


def test_spheres_are_cached_on_disk(
    panda: Robot, panda_spheres: SphereModel, tmp_path, monkeypatch
) -> None:
    """A second fit of the same geometry is read from the cache and equal; another
    cache folder (empty) fits again."""
    again = file_spheres(panda)
    assert again.cached and again.spheres == panda_spheres.spheres
    assert again.self_pairs == panda_spheres.self_pairs
    monkeypatch.setenv("GEOSYN_CACHE_DIR", str(tmp_path))
    fresh = file_spheres(panda, excess=0.05)
    assert not fresh.cached and (tmp_path / "spheres").is_dir()
    assert file_spheres(panda, excess=0.05).cached


def test_self_pairs_exclude_adjacent_links(panda_spheres: SphereModel) -> None:
    """No pair of links on the same joint or on parent and child joints."""
    pairs = {frozenset(p) for p in panda_spheres.self_pairs}
    for i in range(7):
        assert frozenset({f"panda_link{i}", f"panda_link{i + 1}"}) not in pairs
    assert frozenset({"panda_link7", "panda_hand"}) not in pairs  # same joint
    assert frozenset({"panda_link1", "panda_link4"}) in pairs


MJCF = """
<mujoco model="two_links">
  <worldbody>
    <body name="a" pos="0 0 0.1" euler="0.3 0 0">
      <joint name="j1" axis="0 0 1" range="-2 2"/>
      <geom type="box" size="0.04 0.03 0.12" pos="0 0 0.12" euler="0 0.4 0" mass="1"/>
      <geom type="sphere" size="0.01" contype="0" conaffinity="0" mass="0.1"/>
      <body name="b" pos="0 0 0.25">
        <joint name="j2" axis="0 1 0" range="-2 2"/>
        <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.03" mass="0.5"/>
        <geom type="cylinder" size="0.025 0.04" pos="0.2 0 0.03" mass="0.2"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_mjcf_primitives_are_covered(tmp_path, monkeypatch) -> None:
    """The collision geoms of an MJCF (box, capsule, cylinder; a visual-only sphere left
    out) are covered >= margin, their surfaces placed by MuJoCo's own compile."""
    import mujoco

    monkeypatch.setenv("GEOSYN_CACHE_DIR", str(tmp_path))
    path = tmp_path / "two_links.xml"
    path.write_text(MJCF)
    robot = load_robot(path)
    model = file_spheres(robot)
    assert set(model.links) == {"a", "b"}
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    rng = np.random.default_rng(5)
    for _ in range(3):
        q = rng.uniform(-2, 2, 2)
        d.qpos[:] = q
        mujoco.mj_forward(m, d)
        C, R = _world_spheres(robot, model, q)
        for g in range(m.ngeom):
            if not m.geom_contype[g]:
                continue
            s = m.geom_size[g]
            kind = int(m.geom_type[g])
            if kind == mujoco.mjtGeom.mjGEOM_BOX:
                mesh = trimesh.creation.box(extents=2.0 * s)
            elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
                mesh = trimesh.creation.capsule(height=2.0 * s[1], radius=s[0], count=[64, 64])
            else:
                mesh = trimesh.creation.cylinder(radius=s[0], height=2.0 * s[1], sections=128)
            pts, _ = trimesh.sample.sample_surface(mesh, 3000, seed=g)
            local = np.vstack([mesh.vertices, pts])
            world = local @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g]
            assert _depth_inside(world, C, R).min() >= model.margin - 1e-9


def test_subdivide_tiles_each_triangle_in_order() -> None:
    """Seeded triangles of 1 mm to 9 cm: each is cut into k^2 sub-triangles (k = its
    longest edge / spacing, rounded up), in the order of the triangles, that lie in its
    plane and inside it (barycentric coordinates in [0, 1] to 1e-12), have edges <= the
    spacing (to 1e-12 m) and areas that sum to its own (to 1e-12 relative)."""
    rng = np.random.default_rng(3)
    tris = rng.normal(size=(40, 3, 3)) * rng.uniform(0.001, 0.05, size=(40, 1, 1))
    spacing = 0.02
    out = subdivide(tris, spacing)
    edges = np.linalg.norm(tris - np.roll(tris, 1, axis=1), axis=2).max(axis=1)
    ks = np.maximum(1, np.ceil(edges / spacing)).astype(int)
    assert len(out) == int(np.sum(ks**2)) and ks.max() >= 3

    def area(t: np.ndarray) -> np.ndarray:
        return 0.5 * np.linalg.norm(
            np.cross(t[..., 1, :] - t[..., 0, :], t[..., 2, :] - t[..., 0, :]), axis=-1
        )

    start = 0
    for tri, k in zip(tris, ks, strict=True):
        sub = out[start : start + k * k]
        start += k * k
        basis = np.stack([tri[1] - tri[0], tri[2] - tri[0]], axis=1)  # (3, 2)
        coef, *_ = np.linalg.lstsq(basis, (sub.reshape(-1, 3) - tri[0]).T, rcond=None)
        assert np.abs(basis @ coef - (sub.reshape(-1, 3) - tri[0]).T).max() < 1e-12
        assert coef.min() > -1e-12 and coef.sum(axis=0).max() < 1.0 + 1e-12
        assert np.linalg.norm(sub - np.roll(sub, 1, axis=1), axis=2).max() <= spacing + 1e-12
        assert abs(area(sub).sum() - area(tri)) <= 1e-12 * area(tri)


def test_reach_is_the_farthest_outside_point_not_an_inside_one() -> None:
    """A unit cube's surface (12 triangles), its samples every 1 cm: for points at 3, 7
    and 11 cm outside the face centres and the cube's centre (inside, 0.5 m from every
    sample), the reach is 0.11 m (closed form; the centre is not counted); with only
    inside points it is 0."""
    from scipy.spatial import cKDTree

    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    tris = np.asarray(box.vertices)[np.asarray(box.faces)]
    tree = cKDTree(subdivide(tris, 0.01).reshape(-1, 3))
    solid = SolidTest(tris)
    X = np.array([[0.53, 0.0, 0.0], [0.0, -0.57, 0.0], [0.0, 0.0, 0.61], [0.0, 0.0, 0.0]])
    assert abs(_reach(solid, tree, X) - 0.11) < 1e-12
    assert _reach(solid, tree, np.array([[0.0, 0.0, 0.0], [0.1, 0.2, -0.3]])) == 0.0


def test_objects_of_a_link_named_like_a_joint_sit_where_pinocchio_places_them() -> None:
    """The Unitree Z1's URDF has a link and a joint both named ``gripperStator`` (two
    frames of that name in Pinocchio's model; before, reading its collision geometry
    raised Pinocchio's ValueError and no planner could be made). Each collision object
    (`collision_objects`), carried by its joint (``oMi``), sits where Pinocchio's own
    collision model places it (``updateGeometryPlacements`` on the full URDF model) to
    1e-12 m, at 2 seeded configurations; the gripperStator link's objects included."""
    from geosyn.robots.collision_geometry import collision_objects

    robot = load_robot("z1")
    objects = collision_objects(robot)
    assert any(o.link == "gripperStator" for o in objects)
    full, gm = _pinocchio_collision_model(robot)
    assert [o.name for o in objects] == [go.name for go in gm.geometryObjects]
    fdata, gdata, data = full.createData(), pin.GeometryData(gm), robot.model.createData()
    rng = np.random.default_rng(5)
    for _ in range(2):
        q = robot.random_q(rng)
        pin.updateGeometryPlacements(full, fdata, gm, gdata, _full_q(robot, full, q))
        pin.forwardKinematics(robot.model, data, q)
        for k, o in enumerate(objects):
            oMi = data.oMi[robot.joint_id(o.joint)] if o.joint != "universe" else pin.SE3.Identity()
            ours = oMi.homogeneous @ o.placement
            assert np.abs(ours - gdata.oMg[k].homogeneous).max() < 1e-12, o.name
