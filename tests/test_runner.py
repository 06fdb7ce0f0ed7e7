"""The runner: run directory contents, atomic writes, no silent overwrite, report."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from geosyn.experiments import load_config, run_experiment
from geosyn.experiments.errors import ProcedureFailed, RunDirectoryExists
from geosyn.experiments.procedures import PROCEDURES
from geosyn.experiments.results.report import report

FAST = ["outputs.plots=false", "params.steps=100"]


def _planar(extra=()):
    cfg, _ = load_config("planar2_geodesic_vs_euclidean", [*FAST, *extra])
    return cfg


def test_run_directory_contents_and_numbers(tmp_path):
    out = tmp_path / "run"
    outcome = run_experiment(_planar(), out, progress=False, quiet=True)
    assert outcome.path == out
    names = {p.name for p in out.iterdir()}
    assert {"config.yaml", "results.npz", "summary.json", "summary.md", "run.json"} <= names
    assert not list(tmp_path.glob(".*partial*"))
    summary = json.loads((out / "summary.json").read_text())
    assert summary == outcome.summary
    # independent recomputation of the effort from the stored torques
    with np.load(out / "results.npz") as r:
        for path in ("geodesic", "straight"):
            tau = r[f"{path}_computed_torque__tau_applied"]
            cumulative = r[f"{path}_computed_torque__effort"]
            assert summary[f"{path}.effort"] == pytest.approx(np.sum(tau**2) * 1e-3, rel=1e-12)
            assert summary[f"{path}.effort"] == pytest.approx(cumulative[-1], rel=1e-9)
    # the saved config is the resolved one
    saved = yaml.safe_load((out / "config.yaml").read_text())
    assert saved["outputs"]["plots"] is False and saved["params"]["steps"] == 100
    assert "| geodesic |" in (out / "summary.md").read_text()


def test_existing_directory_is_not_overwritten_without_force(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    with pytest.raises(RunDirectoryExists, match="already exists.*--force"):
        run_experiment(_planar(), out, progress=False, quiet=True)
    assert (out / "keep.txt").read_text() == "mine"
    run_experiment(_planar(), out, force=True, progress=False, quiet=True)
    assert not (out / "keep.txt").exists() and (out / "summary.json").is_file()


def test_failed_run_leaves_nothing(tmp_path, monkeypatch):
    proc = PROCEDURES["geodesic_vs_euclidean"]

    def boom(self, ctx):
        (ctx.out_dir / "half_written.npz").write_text("x")
        raise ProcedureFailed("solver failed on purpose")

    monkeypatch.setattr(proc, "run", boom)
    with pytest.raises(ProcedureFailed):
        run_experiment(_planar(), tmp_path / "run", progress=False, quiet=True)
    assert list(tmp_path.iterdir()) == []


def test_report_regenerates_summary_and_plots(tmp_path):
    out = tmp_path / "run"
    first = run_experiment(_planar(["outputs.plots=true"]), out, progress=False, quiet=True)
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert "figure1_configuration_space.png" in pngs and "effort.png" in pngs
    for p in out.glob("*.png"):
        p.unlink()
    (out / "summary.md").unlink()
    (out / "summary.json").unlink()
    again = report(out, quiet=True)
    assert again == first.summary
    assert sorted(p.name for p in out.glob("*.png")) == pngs
    assert (out / "summary.md").is_file()


def test_several_controllers_each_get_a_run(tmp_path):
    cfg = _planar(
        [
            "controllers=[{type: computed_torque}, {type: riemannian_pd, lam: 20, k: 20}, {type: computed_torque, kp: 100, kd: 20}]"
        ]
    )
    assert cfg.controller_labels() == ["computed_torque1", "riemannian_pd", "computed_torque2"]
    outcome = run_experiment(cfg, tmp_path / "run", progress=False, quiet=True)
    s = outcome.summary
    for label in cfg.controller_labels():
        assert s[f"geodesic_{label}.ok"] == 1.0
        assert s[f"geodesic_{label}.effort"] < s[f"straight_{label}.effort"]


def test_pga_synergy_source_gives_g_orthonormal_synergies():
    from geosyn.experiments.run.build import build_metric, build_robot, build_synergies

    cfg, _ = load_config(
        "panda_push_recovery",
        [
            "synergies={type: pga, q0: [0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8], k: 2, n_demos: 8, spread: 0.3}"
        ],
    )
    robot = build_robot(cfg)
    metric = build_metric(cfg, robot)
    syns = build_synergies(cfg, metric, robot)
    assert len(syns) == 2
    V = np.column_stack([s.v0 for s in syns])
    G = metric.G(syns[0].q0)
    np.testing.assert_allclose(V.T @ G @ V, np.eye(2), atol=1e-8)
    # the PGA mean lies near the centre of the demonstrations (spread 0.3 around q0)
    assert np.linalg.norm(syns[0].q0 - np.array(cfg.synergies.q0)) < 0.5


def test_video_is_rendered_with_the_run(tmp_path):
    cfg, _ = load_config(
        "panda_push_recovery",
        [
            "simulation.duration=0.2",
            "controllers=[{type: computed_torque, kp: 900, kd: 60}]",
            "outputs.fps=10",
            "outputs.width=96",
            "outputs.height=72",
            "outputs.plots=false",
        ],
    )
    out = run_experiment(cfg, tmp_path / "run", video=True, progress=False, quiet=True).path
    gif = out / "video_computed_torque.gif"
    from PIL import Image

    with Image.open(gif) as im:
        assert im.size == (96, 72)
        assert im.n_frames == 3  # floor(0.2 s * 10 fps) + 1


def test_default_run_directory_is_unique(tmp_path, monkeypatch):
    from geosyn.experiments.run.runner import default_run_dir

    monkeypatch.chdir(tmp_path)
    cfg = _planar()
    first = run_experiment(cfg, progress=False, quiet=True).path
    assert first.parent == Path("runs") and first.name.startswith("planar2_geodesic_vs_euclidean-")
    monkeypatch.setattr("time.strftime", lambda fmt, t=None: "20260101-000000")
    a = default_run_dir(cfg)
    a.mkdir(parents=True)
    b = default_run_dir(cfg)
    assert (a.name, b.name) == (
        "planar2_geodesic_vs_euclidean-20260101-000000",
        "planar2_geodesic_vs_euclidean-20260101-000000-2",
    )


def test_explicit_synergies_and_every_disturbance_type(tmp_path):
    from geosyn.experiments.run.build import (
        build_disturbances,
        build_metric,
        build_reference,
        build_robot,
        build_synergies,
    )
    from geosyn.sim import Latency, PayloadChange, Push, SensorNoise, TorqueNoise, Wrench

    q0 = [0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8]
    v1, v2 = [0.2, 0, 0, 0, 0, 0, 0], [0, 0, 0, 0.3, 0, 0.1, 0]
    cfg, _ = load_config(
        "panda_push_recovery",
        [
            f"synergies={{type: explicit, items: [{{q0: {q0}, v0: {v1}}}, {{q0: {q0}, v0: {v2}}}]}}",
            "reference.weights=[2.0, -1.0]",
            "simulation.duration=0.2",
            "outputs.plots=false",
            "controllers=[{type: computed_torque, kp: 900, kd: 60}]",
            "disturbances=[{type: push, body: panda_link5, force: [5, 0, 0], start: 0.05, duration: 0.05},"
            " {type: wrench, body: panda_link7, torque: [0, 0, 0.5], period: 0.1},"
            " {type: payload_change, time: 0.1, mass: 0.2, payload: object},"
            " {type: torque_noise, std: 0.01}, {type: sensor_noise, q_std: 1.0e-5},"
            " {type: latency, ticks: 1}]",
        ],
    )
    kinds = [type(d) for d in build_disturbances(cfg)]
    assert kinds == [Push, Wrench, PayloadChange, TorqueNoise, SensorNoise, Latency]
    robot = build_robot(cfg)
    metric = build_metric(cfg, robot)
    ref, geo = build_reference(cfg, metric, build_synergies(cfg, metric, robot))
    # common base: the combination's initial velocity is the weighted sum (no transport)
    np.testing.assert_allclose(geo.v[0], 2.0 * np.array(v1) - np.array(v2), atol=1e-12)
    s = run_experiment(cfg, tmp_path / "run", progress=False, quiet=True).summary
    assert s["computed_torque.ok"] == 1.0


def test_a_run_with_plots_leaves_matplotlib_global_state_alone(tmp_path):
    """Plots draw on their own Agg canvases: no pyplot, no backend switch (in a fresh
    interpreter, where nothing else has touched matplotlib)."""
    import subprocess
    import sys

    code = """
import sys
from pathlib import Path
import matplotlib
backend = lambda: dict.__getitem__(matplotlib.rcParams, "backend")  # unresolved value
before = backend()
from geosyn.experiments import load_config, run_experiment
cfg, _ = load_config(
    "planar2_geodesic_vs_euclidean",
    ["params.steps=60", "params.duration=0.3", "simulation.duration=0.3"],
)
out = run_experiment(cfg, sys.argv[1], progress=False, quiet=True).path
assert (out / "effort.png").is_file() and (out / "figure1_configuration_space.png").is_file()
assert backend() == before, (before, backend())
assert "matplotlib.pyplot" not in sys.modules
"""
    proc = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path / "run")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
