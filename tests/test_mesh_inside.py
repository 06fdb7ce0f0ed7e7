"""Inside test of closed triangle surfaces (`geosyn.robots.mesh_inside`).

References: closed forms (a convex polyhedron's face planes; a polygonal annulus as the
outer prism minus the inner one; two overlapping boxes as their union) and, on a robot's
own STL meshes, the generalized winding number (the solid angle of every triangle,
Van Oosterom-Strackee), a different formula on the same surface.
"""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial import ConvexHull

from geosyn.robots import load_robot
from geosyn.robots.collision_geometry import collision_objects, surface_triangles
from geosyn.robots.mesh_inside import SolidTest

TOL = 1e-6
"""Points closer than this [m] to a face plane are left out of the comparisons (on the
surface, inside and outside are both right)."""


def _in_hull(points: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(inside, clear): X strictly inside the convex hull of ``points``, and farther than
    TOL from each face plane."""
    eq = ConvexHull(points).equations
    s = X @ eq[:, :3].T + eq[:, 3]
    return s.max(axis=1) < 0.0, np.abs(s).min(axis=1) > TOL


def _tris(mesh: trimesh.Trimesh) -> np.ndarray:
    return np.asarray(mesh.vertices)[np.asarray(mesh.faces)]


def _winding(tris: np.ndarray, X: np.ndarray, chunk: int = 20) -> np.ndarray:
    """(K,) generalized winding number of X (K, 3) on ``tris`` (F, 3, 3), ``chunk``
    points at a time (bounded memory)."""
    out = []
    for i in range(0, len(X), chunk):
        A, B, C = (tris[None, :, j, :] - X[i : i + chunk, None, :] for j in range(3))
        a, b, c = (np.linalg.norm(v, axis=2) for v in (A, B, C))
        det = np.einsum("kfi,kfi->kf", A, np.cross(B, C))
        den = (a * b * c + np.einsum("kfi,kfi->kf", A, B) * c
               + np.einsum("kfi,kfi->kf", B, C) * a + np.einsum("kfi,kfi->kf", C, A) * b)  # fmt: skip
        out.append(np.arctan2(det, den).sum(axis=1) / (2.0 * np.pi))
    return np.concatenate(out)


def test_points_inside_a_convex_polyhedron_are_those_behind_every_face() -> None:
    """An icosphere (320 faces) and a 6-sided cylinder: 4,000 seeded points each, the
    answer equals 'behind every face plane' at every point farther than 1e-6 m from them."""
    rng = np.random.default_rng(0)
    for mesh in (trimesh.creation.icosphere(subdivisions=2, radius=0.3),
                 trimesh.creation.cylinder(radius=0.05, height=0.4, sections=6)):  # fmt: skip
        X = rng.uniform(mesh.bounds[0] - 0.05, mesh.bounds[1] + 0.05, (4000, 3))
        truth, clear = _in_hull(np.asarray(mesh.vertices), X)
        got = SolidTest(_tris(mesh)).contains(X)
        assert np.array_equal(got[clear], truth[clear])
        assert 0.1 < truth.mean() < 0.9  # both answers occur


def test_points_inside_a_polygonal_annulus_are_in_the_outer_prism_not_the_inner() -> None:
    """A non-convex closed mesh: trimesh's annulus (radii 0.1 and 0.2 m, 24 sections). A
    point is inside when it is in the outer prism and not in the inner one (closed form
    from the two vertex rings); 4,000 seeded points, those near a face left out."""
    mesh = trimesh.creation.annulus(r_min=0.1, r_max=0.2, height=0.1, sections=24)
    V = np.asarray(mesh.vertices)
    r = np.linalg.norm(V[:, :2], axis=1)
    rng = np.random.default_rng(1)
    X = rng.uniform((-0.25, -0.25, -0.07), (0.25, 0.25, 0.07), (4000, 3))
    outer, clear_o = _in_hull(V[r > 0.15], X)
    hole, clear_i = _in_hull(V[r < 0.15], X)
    truth, clear = outer & ~hole, clear_o & clear_i
    got = SolidTest(_tris(mesh)).contains(X)
    assert np.array_equal(got[clear], truth[clear])
    assert truth.sum() > 500 and (hole & clear).sum() > 100  # the hole is tested


def test_two_overlapping_meshes_of_one_link_are_their_union() -> None:
    """Two boxes that overlap (one link of two meshes): inside either box is inside (the
    winding number there is 2); 3,000 seeded points against the closed form."""
    a = trimesh.creation.box(extents=(0.2, 0.1, 0.1))
    b = trimesh.creation.box(extents=(0.1, 0.3, 0.1))
    b.apply_translation((0.05, 0.05, 0.02))
    rng = np.random.default_rng(2)
    X = rng.uniform(-0.2, 0.25, (3000, 3))
    in_a, clear_a = _in_hull(np.asarray(a.vertices), X)
    in_b, clear_b = _in_hull(np.asarray(b.vertices), X)
    solid = SolidTest(np.vstack([_tris(a), _tris(b)]))
    clear = clear_a & clear_b
    assert np.array_equal(solid.contains(X)[clear], (in_a | in_b)[clear])
    both = in_a & in_b & clear
    assert both.sum() > 20 and np.all(solid.winding(X[both]) == 2.0)


def test_a_robot_stl_mesh_agrees_with_the_generalized_winding_number() -> None:
    """The xArm7's link 6 (7,986 triangles of its STL file) and link 2: at 300 seeded
    points in each bounding box the answer equals the generalized winding number's
    (|w| > 1/2), and that number is within 1e-3 of 0 or 1 there (closed surfaces but for
    link 6's 10 unshared edges)."""
    robot = load_robot("xarm7")
    rng = np.random.default_rng(3)
    for link in ("link6", "link2"):
        tris = np.vstack([surface_triangles(o) for o in collision_objects(robot)
                          if o.link == link])  # fmt: skip
        assert len(tris) > 4000
        lo, hi = tris.reshape(-1, 3).min(axis=0), tris.reshape(-1, 3).max(axis=0)
        X = rng.uniform(lo, hi, (300, 3))
        w = _winding(tris, X)
        assert np.abs(w - np.round(w)).max() < 1e-3
        got = SolidTest(tris).contains(X)
        assert np.array_equal(got, np.abs(w) > 0.5)
        assert 10 < got.sum() < 290
