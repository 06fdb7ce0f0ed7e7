"""Rendering: headless frames, GIF with the expected frame count, mp4 or a clear error."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from conftest import get_robot
from geosyn.core.errors import InvalidArgument
from geosyn.sim import CameraView, Clip, RenderError, Simulation, render_video
from geosyn.sim.offscreen import gl_backend
from geosyn.sim.render import frame_indices
from geosyn.world import Payload, Sphere


class HoldPD:
    def __init__(self, robot):
        import pinocchio as pin

        self.pin, self.robot, self.data = pin, robot, robot.model.createData()

    def reset(self, q, v, t=0.0):
        self.q0 = np.array(q)

    def compute(self, t, q, v):
        g = self.pin.computeGeneralizedGravity(self.robot.model, self.data, q)
        return g + 100.0 * (self.q0 - q) - 20.0 * v


@pytest.fixture(scope="module")
def run():
    robot = get_robot("panda")
    q0 = robot.neutral()
    q0[3], q0[5] = -1.5, 1.5
    res = Simulation(robot, HoldPD(robot)).run(q0, np.full(7, 0.5), 0.3)
    return robot, res


def test_frame_indices():
    robot = get_robot("planar2")
    res = Simulation(robot, HoldPD(robot), control_dt=0.01).run(np.zeros(2), None, 1.0)
    idx = frame_indices(res, fps=4)
    assert np.array_equal(idx, [0, 25, 50, 75, 100])  # 100 is the final state
    assert len(frame_indices(res, fps=30)) == 31


def test_gif_has_expected_frames(run, tmp_path):
    robot, res = run
    obstacles = [Sphere((0.5, 0.3, 0.4), 0.1)]
    path = render_video(
        res,
        tmp_path / "clip.gif",
        robot,
        fps=10,
        width=160,
        height=120,
        payloads=[Payload("panda_hand_tcp", 1.0)],
        obstacles=obstacles,
    )
    with Image.open(path) as im:
        assert im.n_frames == 4  # floor(0.3 s * 10 fps) + 1
        assert im.size == (160, 120)
        assert im.info["duration"] == 100
        im.seek(0)
        first = np.asarray(im.convert("RGB"), dtype=float)
        im.seek(3)
        last = np.asarray(im.convert("RGB"), dtype=float)
    assert first.std() > 10.0  # something is drawn, not a blank image
    assert np.abs(first - last).mean() > 0.1  # the robot moved (v0 = 0.5 rad/s)


def test_frames_show_the_robot(run):
    """The robot occupies the centre of the auto-framed view: a view aimed away differs."""
    robot, res = run
    frames = Clip(res, robot, fps=5, width=96, height=72, trail=False).render()
    assert frames.shape == (2, 72, 96, 3) and frames.dtype == np.uint8
    away = Clip(
        res,
        robot,
        fps=5,
        width=96,
        height=72,
        trail=False,
        camera=CameraView((10.0, 10.0, 5.0), 1.0, 0.0, 0.0),
    ).render()
    assert np.abs(frames.astype(float) - away).mean() > 5.0


def test_mp4_has_expected_frames(run, tmp_path):
    """The ``video`` extra (imageio + its bundled ffmpeg) is installed by ``make test``."""
    import imageio.v2 as iio

    robot, res = run
    path = render_video(res, tmp_path / "clip.mp4", robot, fps=10, width=64, height=48)
    with iio.get_reader(path) as reader:
        frames = [f for f in reader]
    expected = int(np.floor(res.n_ticks * res.control_dt * 10 + 1e-9)) + 1  # 0.3 s -> 4
    assert len(frames) == expected
    assert frames[0].shape == (48, 64, 3)


def test_mp4_without_imageio_is_a_clear_error(run, tmp_path, monkeypatch):
    import builtins

    real_import = builtins.__import__

    def no_imageio(name, *args, **kwargs):
        if name.startswith("imageio"):
            raise ImportError(name)
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_imageio)
    robot, res = run
    with pytest.raises(RenderError, match="imageio"):
        render_video(res, tmp_path / "clip.mp4", robot, fps=5, width=64, height=48)
    assert not (tmp_path / "clip.mp4").exists()


def test_bad_render_input(run, tmp_path):
    robot, res = run
    with pytest.raises(InvalidArgument, match=r"\.gif, \.mp4"):
        render_video(res, tmp_path / "clip.avi", robot)
    with pytest.raises(InvalidArgument, match="width"):
        Clip(res, robot, width=5000)
    with pytest.raises(InvalidArgument, match="robot 'panda'"):
        Clip(res, get_robot("ur5"))
    with pytest.raises(InvalidArgument, match="fps"):
        Clip(res, robot, fps=0.0)


def test_write_frames_streams_and_checks(tmp_path):
    from geosyn.sim.video import write_frames

    def gen():
        for i in range(3):
            frame = np.zeros((8, 10, 3), dtype=np.uint8)
            frame[:, i] = 255
            yield frame

    path = write_frames(gen(), tmp_path / "s.gif", fps=20)
    with Image.open(path) as im:
        assert im.n_frames == 3 and im.size == (10, 8) and im.info["duration"] == 50
        im.seek(2)
        assert np.asarray(im.convert("RGB"))[0, 2].tolist() == [255, 255, 255]
    bad = [np.zeros((8, 10, 3), np.uint8), np.zeros((8, 11, 3), np.uint8)]
    with pytest.raises(InvalidArgument, match="frame 1 must be a"):
        write_frames(bad, tmp_path / "b.gif")
    with pytest.raises(InvalidArgument, match="empty"):
        write_frames([], tmp_path / "e.gif")


def test_render_a_run_ending_non_finite():
    """A log whose final state is not finite renders (the last finite state is shown)."""
    import dataclasses

    robot = get_robot("planar2")
    res = Simulation(robot, HoldPD(robot), control_dt=0.01).run(np.zeros(2), [2.0, -1.0], 0.2)
    broken = dataclasses.replace(res, q_final=np.array([np.nan, 0.0]))
    view = CameraView((0.0, 0.0, 0.0), 4.0, 90.0, -89.0)
    frames = Clip(broken, robot, fps=10, width=64, height=48, camera=view, trail=False).render()
    assert frames.shape == (3, 48, 64, 3)
    full = Clip(res, robot, fps=10, width=64, height=48, camera=view, trail=False).render()
    assert np.array_equal(frames[:2], full[:2])
    assert frames[-1].std() > 5.0  # a drawn scene, not a blank or broken frame


# -- no global state ---------------------------------------------------------------------
_PROBE = """
import json, os, sys
before = dict(os.environ)
import mujoco
gl_module = sys.modules.get("mujoco.rendering.classic.gl_context") or mujoco.gl_context
gl_class = gl_module.GLContext
import geosyn.sim
print(json.dumps({
    "environ_unchanged": dict(os.environ) == before,
    "mujoco_gl_context_unchanged": gl_module.GLContext is gl_class,
}))
"""


def test_importing_geosyn_sim_changes_nothing_global():
    """A fresh interpreter: importing geosyn.sim sets no variable and patches no module."""
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    out = subprocess.run(
        [sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, check=True
    )
    assert json.loads(out.stdout.strip().splitlines()[-1]) == {
        "environ_unchanged": True,
        "mujoco_gl_context_unchanged": True,
    }


def test_rendering_restores_the_environment(run, monkeypatch):
    """MUJOCO_GL unset: EGL is chosen at render time; the environment is left as it was."""
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    robot, res = run
    before = dict(os.environ)
    assert gl_backend() == "egl"
    frames = Clip(res, robot, fps=5, width=32, height=24, trail=False).render()
    assert frames.shape == (2, 24, 32, 3)
    assert dict(os.environ) == before


def test_unknown_backend_is_one_clear_error(run, monkeypatch):
    monkeypatch.setenv("MUJOCO_GL", "vulkan")
    robot, res = run
    with pytest.raises(RenderError, match="MUJOCO_GL='vulkan'.*egl"):
        Clip(res, robot, fps=5, width=32, height=24).render()


# -- what a frame shows ------------------------------------------------------------------
def _planar_push_run():
    """planar2 holding still, pushed from 0.1 s to 0.2 s (sideways in its plane)."""
    from geosyn.sim import Push

    robot = get_robot("planar2")
    push = Push(robot.joint_names[1], [0.0, 40.0, 0.0], 0.1, 0.1)
    res = Simulation(robot, HoldPD(robot), control_dt=0.01, disturbances=[push]).run(
        np.array([0.3, 0.6]), None, 0.3
    )
    return robot, res, push


def _red(frame: np.ndarray) -> int:
    """Pixels of the force arrow's red (0.85, 0.1, 0.1), shading allowed."""
    r, g, b = (frame[..., i].astype(int) for i in range(3))
    return int(np.count_nonzero((r > 120) & (r > 3 * g) & (r > 3 * b)))


def test_push_arrow_is_drawn_while_the_push_acts():
    """Frames at 0, 0.1, 0.2, 0.3 s: the arrow (red) only in the frame at 0.1 s."""
    robot, res, push = _planar_push_run()
    view = CameraView((0.0, 0.0, 0.0), 4.0, 90.0, -89.0)
    kw = dict(fps=10, width=240, height=180, camera=view, trail=False, overlay=False)
    with_arrow = Clip(res, robot, disturbances=[push], **kw).render()
    without = Clip(res, robot, **kw).render()
    red = [_red(f) for f in with_arrow]
    assert red[1] > 15 and red[0] == red[2] == red[3] == 0, red
    assert np.array_equal(with_arrow[[0, 2, 3]], without[[0, 2, 3]])


def test_overlay_shows_label_time_and_legend():
    """The overlay draws in the top-left (label, time) and bottom-left (legend) corners
    only; the legend's first entry is in the reference path's green."""
    robot, res, _ = _planar_push_run()
    res = dataclasses.replace(res, q_ref=res.q + 0.05)
    view = CameraView((0.0, 0.0, 0.0), 4.0, 90.0, -89.0)
    kw = dict(fps=10, width=320, height=240, camera=view)
    on = Clip(res, robot, label="computed_torque", **kw).render()[1].astype(int)
    off = Clip(res, robot, overlay=False, **kw).render()[1].astype(int)
    diff = np.abs(on - off).max(axis=2) > 0
    assert diff[:40, :120].mean() > 0.05  # label and time stamp, top left
    assert diff[200:, :200].mean() > 0.02  # legend, bottom left
    assert not diff[90:180, 200:].any()  # the scene itself is untouched
    legend = on[200:, :200]
    green = (legend[..., 1] > 150) & (legend[..., 0] < 100) & (legend[..., 2] < 150)
    assert green.sum() > 20


def test_a_motion_renders_like_its_log(run):
    """`Motion.from_result` (ticks + final state) gives the same frames as the log."""
    from geosyn.sim import Motion

    robot, res = run
    kw = dict(fps=10, width=64, height=48, trail=False, meshes=False)
    a = Clip(res, robot, **kw).render()
    b = Clip(Motion.from_result(res), robot, **kw).render()
    assert np.array_equal(a, b)


def test_a_bad_motion_is_one_clear_error():
    from geosyn.sim import Motion

    robot = get_robot("planar2")
    with pytest.raises(InvalidArgument, match=r"motion must have t \(T,\), q and q_ref"):
        Clip(Motion(np.arange(3.0), np.zeros((3, 3))), robot)
    with pytest.raises(InvalidArgument, match="increasing"):
        Clip(Motion(np.zeros(3), np.zeros((3, 2))), robot)


def test_the_robots_own_meshes_are_drawn(run):
    """Panda: MuJoCo compiles its URDF's collision meshes, which pose like the simulated
    model (joint anchors within MESH_TOLERANCE); the frames differ from the capsules'."""
    from geosyn.sim.render_scene import MESH_TOLERANCE, FrameScene, _joint_qpos, _poses_alike

    robot, res = run
    scene = FrameScene(robot)
    assert scene.has_meshes and scene.mesh_note == ""
    assert scene.model.nmesh >= 8
    assert _poses_alike(robot, scene.model, _joint_qpos(scene.model, robot)) < MESH_TOLERANCE
    kw = dict(fps=5, width=96, height=72, trail=False, overlay=False)
    meshes = Clip(res, robot, **kw).render().astype(float)
    capsules = Clip(res, robot, meshes=False, **kw).render()
    assert np.abs(meshes - capsules).mean() > 2.0


def test_capsules_when_the_file_has_no_meshes():
    """A robot file without meshes (or no file at all) is drawn with capsules, and says so."""
    from geosyn.robots import load_robot
    from geosyn.sim.render_scene import FrameScene

    here = os.path.dirname(__file__)
    robot = load_robot(os.path.join(here, "fixtures", "arm_root_quat.xml"))
    assert "has no meshes" in FrameScene(robot).mesh_note
    assert "no model file" in FrameScene(get_robot("planar2")).mesh_note
