"""Perception of a coloured ball: rendered RGB-D images, back-projection, sphere fit."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from geosyn.robots import load_robot
from geosyn.sim import CameraView, build_scene
from geosyn.sim.camera_sensor import RGBDRenderer, pinhole_camera
from geosyn.sim.perception import (
    PinholeCamera,
    colour_mask,
    estimate_ball,
    fit_sphere,
    pixel_points,
)
from geosyn.world import Sphere

GREEN = (0.1, 0.85, 0.1, 1.0)
RADIUS = 0.03
VIEW = CameraView((0.45, 0.0, 0.35), 1.3, azimuth=180.0, elevation=-30.0)


@pytest.fixture(scope="module")
def rendered():
    """Four seeded ball positions in front of the panda, each rendered once (RGB-D)."""
    robot = load_robot("panda")
    q = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
    rng = np.random.default_rng(14)
    centres = np.array([0.45, 0.0, 0.35]) + rng.uniform(-0.15, 0.15, size=(4, 3))
    scene = build_scene(robot, obstacles=[Sphere(tuple(centres[0]), RADIUS)])
    gid = int(scene.obstacle_geom_ids[0])
    scene.model.geom_rgba[gid] = GREEN
    data = mujoco.MjData(scene.model)
    data.qpos[scene.qpos_adr] = q
    shots = []
    with RGBDRenderer(scene.model, 320, 240) as r:
        for c in centres:
            scene.model.geom_pos[gid] = c
            mujoco.mj_kinematics(scene.model, data)
            r.update(data, VIEW.mjv_camera())
            rgb, depth = r.render_rgbd()
            shots.append((c, rgb, depth, pinhole_camera(r, 320, 240)))
    return shots


def test_estimated_ball_centre_is_within_5_mm_of_the_truth(rendered):
    for centre, rgb, depth, cam in rendered:
        est = estimate_ball(cam, rgb, depth, GREEN[:3], RADIUS)
        assert est is not None and est.pixels >= 20
        assert np.linalg.norm(est.position - centre) <= 5e-3
        assert est.covariance.shape == (3, 3) and np.all(est.std >= 0.0)


def test_camera_model_matches_the_rendering(rendered):
    centre, rgb, depth, cam = rendered[0]
    # the ball's centre projects into its segmented blob (within a pixel of its middle)
    rows, cols = np.nonzero(colour_mask(rgb, GREEN[:3]))
    row, col, z = cam.project(centre[None, :])[0]
    assert abs(row - rows.mean()) <= 1.5 and abs(col - cols.mean()) <= 1.5
    # depth along the optical axis at the blob's middle: the sphere's near surface,
    # z - r / cos(angle off axis) for a point on the ray through the centre, ~ z - r
    d = depth[int(round(row)), int(round(col))]
    assert abs(d - (z - RADIUS)) <= 2e-3
    # the far plane and the floor are farther than the ball everywhere
    assert depth.min() > 0.5


def test_sphere_fit_recovers_an_exact_centre_and_back_projection_inverts_projection():
    rng = np.random.default_rng(3)
    c = np.array([0.4, -0.1, 0.3])
    d = rng.normal(size=(200, 3))
    d[:, 0] = -np.abs(d[:, 0])  # the cap seen from a camera at +x
    pts = c + RADIUS * d / np.linalg.norm(d, axis=1, keepdims=True)
    centre, cov, rms = fit_sphere(pts, RADIUS, toward=np.array([2.0, 0.0, 0.3]))
    np.testing.assert_allclose(centre, c, atol=1e-9)
    assert rms < 1e-12 and np.all(np.abs(cov) < 1e-20)
    cam = PinholeCamera(
        np.array([2.0, 0.1, 0.5]),
        np.array([-1.0, 0.0, 0.0]),
        np.array([0.0, 0.0, 1.0]),
        300.0,
        320,
        240,
    )
    world = np.array([[0.3, 0.2, 0.4], [0.5, -0.1, 0.6]])
    rc = cam.project(world)
    depth = np.zeros((240, 320))
    rows, cols = np.round(rc[:, 0]).astype(int), np.round(rc[:, 1]).astype(int)
    # put the points exactly on pixel centres, then back-project them
    on_grid = pixel_points(cam, depth + 1.0, rows, cols)
    rc2 = cam.project(on_grid)
    np.testing.assert_allclose(rc2[:, :2], np.stack([rows, cols], axis=1), atol=1e-9)
    np.testing.assert_allclose(rc2[:, 2], 1.0, atol=1e-12)


def test_colour_mask_ignores_shading_and_a_missing_ball_is_none():
    img = np.zeros((4, 4, 3), dtype=np.uint8)
    img[0, 0] = (25, 212, 25)  # bright green
    img[0, 1] = (10, 85, 10)  # the same green in shadow
    img[0, 2] = (200, 200, 200)  # grey
    img[0, 3] = (2, 17, 2)  # too dark to judge
    mask = colour_mask(img, GREEN[:3])
    assert mask[0].tolist() == [True, True, False, False]
    cam = PinholeCamera(np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 0, 1.0]), 100.0, 4, 4)
    assert estimate_ball(cam, img, np.ones((4, 4)), GREEN[:3], RADIUS) is None
