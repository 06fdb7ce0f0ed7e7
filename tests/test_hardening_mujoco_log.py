"""MuJoCo's log never lands in the current directory (issue 23): sweeps, ``geosyn report``
and ``geosyn view`` keep MuJoCo's warnings in the run (or sweep) directory's
``MUJOCO_LOG.TXT`` as ``geosyn run`` does; ``geosyn sweep --allow-unused`` runs a config
with sections its kind does not read, which it refuses without the flag."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from geosyn.experiments.cli import main

SRC = "planar2_geodesic_vs_euclidean"
FAST = ["--set", "outputs.plots=false", "--set", "params.steps=60", "--no-progress"]
UNUSED = "synergies={type: designed, q0: [0, 0], k: 1}"  # kind geodesic_vs_euclidean: unread


def _mujoco_warns() -> None:
    """A real MuJoCo warning (a NaN state, as a diverging run gives)."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body><joint/><geom size=".1"/></body></worldbody></mujoco>'
    )
    data = mujoco.MjData(model)
    data.qpos[0] = np.nan
    mujoco.mj_step(model, data)


def _noisy(real: Any) -> Any:
    @functools.wraps(real)
    def call(*args: Any, **kwargs: Any) -> Any:
        _mujoco_warns()
        return real(*args, **kwargs)

    return call


def test_sweep_runs_keep_mujoco_warnings_in_their_directories(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from geosyn.experiments.sweep import run_sweep

    monkeypatch.setattr(run_sweep, "run_experiment", _noisy(run_sweep.run_experiment))
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "sweep"
    grid = ["--grid", "controllers.0.kp=100,200"]
    assert main(["sweep", SRC, "--out", str(out), *grid, *FAST]) == 0
    logs = sorted(out.rglob("MUJOCO_LOG.TXT"))
    assert [p.parent.name for p in logs] == ["seed0", "seed0"]
    assert all("QPOS" in p.read_text() for p in logs)
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_report_and_view_keep_mujoco_warnings_in_the_run_directory(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from geosyn.experiments import viewer
    from geosyn.experiments.results import report

    run = tmp_path / "run"
    assert main(["run", SRC, "--out", str(run), *FAST]) == 0
    assert not (run / "MUJOCO_LOG.TXT").exists()
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(report, "report", _noisy(report.report))
    assert main(["report", str(run)]) == 0
    assert (run / "MUJOCO_LOG.TXT").read_text().count("QPOS") == 1

    class _Viewer:
        url = "http://127.0.0.1:0"

        def serve_forever(self) -> None:
            _mujoco_warns()  # while serving, as a replay's forward kinematics may

    monkeypatch.setattr(viewer, "view_run", lambda *a, **k: _Viewer())
    assert main(["view", str(run), "--port", "0"]) == 0
    assert (run / "MUJOCO_LOG.TXT").read_text().count("QPOS") == 2
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_sweep_allow_unused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = ["sweep", SRC, "--grid", "seed=0", "--set", UNUSED, *FAST]
    assert main([*args, "--out", str(tmp_path / "refused")]) == 2
    err = capsys.readouterr().err
    assert "--allow-unused" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "refused").exists()
    assert main([*args, "--out", str(tmp_path / "ok"), "--allow-unused"]) == 0
    (summary,) = (tmp_path / "ok").rglob("summary.json")
    assert "synergies" in (summary.parent / "config.yaml").read_text()
    assert "does not read section 'synergies'" in (summary.parent / "run.log").read_text()
