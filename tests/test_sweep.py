"""Sweeps: grid x seeds, resume after an interruption, aggregate, process pool, Ray."""

from __future__ import annotations

import json

import numpy as np
import pytest

import geosyn.experiments.sweep as sweep_mod
from geosyn.core.errors import InvalidArgument
from geosyn.experiments.errors import ConfigError, RunDirectoryExists
from geosyn.experiments.sweep import parse_grid, point_name, sweep

SRC = "planar2_geodesic_vs_euclidean"
BASE = [
    "outputs.plots=false",
    "params.steps=60",
    "params.duration=0.3",
    "simulation.duration=0.3",
    "disturbances=[{type: torque_noise, std: 0.05}]",
]


def test_parse_grid():
    assert parse_grid(["a.b=1,2", "c=[1,2],[3,4]"]) == {"a.b": ["1", "2"], "c": ["[1,2]", "[3,4]"]}
    for bad in (["a"], ["=1"], ["a="], ["a=1,"]):
        with pytest.raises(ConfigError, match="--grid"):
            parse_grid(bad)
    with pytest.raises(ConfigError, match="twice"):
        parse_grid(["a=1", "a=2"])
    assert (
        point_name({"controllers.0.kp": "100", "x": "[1, 2]"}) == "controllers.0.kp=100__x=_1,_2_"
    )


def _timestamps(out):
    return {
        p.parent.relative_to(out).as_posix(): json.loads(p.read_text())["finished_ns"]
        for p in out.glob("*/seed*/run.json")
    }


def test_interrupted_sweep_completes_only_missing_runs(tmp_path, monkeypatch):
    out = tmp_path / "sweep"
    grid = {"controllers.0.kp": ["100", "400"]}
    real = sweep_mod.run_job
    calls = []

    def dies_after_three(job):
        if len(calls) == 3:
            raise KeyboardInterrupt("killed")  # like a Ctrl-C / kill in the middle of the sweep
        calls.append(job.out)
        return real(job)

    monkeypatch.setattr(sweep_mod, "run_job", dies_after_three)
    with pytest.raises(KeyboardInterrupt):
        sweep(SRC, grid, seeds=3, out=out, overrides=BASE, progress=False)
    first = _timestamps(out)
    assert len(first) == 3
    assert not list(out.glob("*/.*partial*"))

    rerun = []

    def counting(job):
        rerun.append(job.out)
        return real(job)

    monkeypatch.setattr(sweep_mod, "run_job", counting)
    result = sweep(SRC, grid, seeds=3, out=out, overrides=BASE, progress=False)
    assert (result.ran, result.skipped) == (3, 3)
    assert sorted(rerun) == sorted(set(str(out / p) for p in _timestamps(out)) - set(calls))
    after = _timestamps(out)
    assert len(after) == 6
    for run, stamp in first.items():  # finished runs were not redone
        assert after[run] == stamp

    # aggregate: mean and std per grid point, recomputed from the runs' summary.json
    rows = json.loads((out / "sweep_summary.json").read_text())
    assert [r["point"] for r in rows] == [{"controllers.0.kp": "100"}, {"controllers.0.kp": "400"}]
    for row in rows:
        vals = [
            json.loads((out / point_name(row["point"]) / f"seed{s}" / "summary.json").read_text())[
                "straight.effort"
            ]
            for s in range(3)
        ]
        assert row["n_runs"] == 3
        assert row["metrics"]["straight.effort"]["mean"] == pytest.approx(np.mean(vals), rel=1e-12)
        assert row["metrics"]["straight.effort"]["std"] == pytest.approx(np.std(vals), rel=1e-12)
        assert row["metrics"]["straight.effort"]["std"] > 0  # torque noise differs by seed
    assert "straight.effort" in (out / "sweep_summary.md").read_text()

    # nothing left: a third call runs nothing
    again = sweep(SRC, grid, seeds=3, out=out, overrides=BASE, progress=False)
    assert (again.ran, again.skipped) == (0, 6)


def test_foreign_directory_is_refused(tmp_path):
    out = tmp_path / "sweep"
    sweep(SRC, {"controllers.0.kp": ["100"]}, seeds=1, out=out, overrides=BASE, progress=False)
    with pytest.raises(RunDirectoryExists, match="different sweep"):
        sweep(SRC, {"controllers.0.kp": ["200"]}, seeds=1, out=out, overrides=BASE, progress=False)
    other = tmp_path / "other"
    other.mkdir()
    (other / "file").write_text("x")
    with pytest.raises(RunDirectoryExists, match="not a sweep directory"):
        sweep(SRC, {}, seeds=1, out=other, overrides=BASE, progress=False)
    with pytest.raises(InvalidArgument, match="seeds"):
        sweep(SRC, {}, seeds=0, out=tmp_path / "z", overrides=BASE, progress=False)


@pytest.mark.slow
def test_process_pool_matches_in_process(tmp_path):
    grid = {"controllers.0.kp": ["100", "400"]}
    a = sweep(SRC, grid, seeds=1, out=tmp_path / "a", overrides=BASE, progress=False, workers=1)
    b = sweep(SRC, grid, seeds=1, out=tmp_path / "b", overrides=BASE, progress=False, workers=2)
    assert b.ran == 2
    for ra, rb in zip(a.aggregate, b.aggregate, strict=True):
        assert ra["metrics"]["straight.effort"]["mean"] == rb["metrics"]["straight.effort"]["mean"]


@pytest.mark.slow
def test_ray_local(tmp_path):
    import ray  # the distributed extra; CI installs it, so this must not be skipped

    grid = {"controllers.0.kp": ["100", "400"]}
    local = sweep(SRC, grid, seeds=1, out=tmp_path / "local", overrides=BASE, progress=False)
    res = sweep(
        SRC,
        grid,
        seeds=1,
        out=tmp_path / "ray",
        overrides=BASE,
        progress=False,
        ray_address="local",
        workers=2,
    )
    assert not ray.is_initialized()
    assert (res.ran, res.skipped) == (2, 0)
    for ra, rb in zip(local.aggregate, res.aggregate, strict=True):
        assert ra["metrics"]["straight.effort"]["mean"] == rb["metrics"]["straight.effort"]["mean"]


@pytest.mark.slow
def test_sweep_killed_by_sigterm_then_resumed(tmp_path, monkeypatch):
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    out = tmp_path / "sweep"
    script = Path(sys.executable).with_name("geosyn")
    args = [
        "sweep",
        SRC,
        "--grid",
        "controllers.0.kp=100,200,300,400",
        "--seeds",
        "2",
        "--out",
        str(out),
        "--no-progress",
    ]
    for o in [*BASE, "simulation.duration=1.0", "params.duration=1.0"]:
        args += ["--set", o]
    proc = subprocess.Popen(
        [str(script), *args],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
    )
    deadline = time.monotonic() + 120
    while len(list(out.glob("*/seed*/summary.json"))) < 2 and time.monotonic() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode != 0, f"sweep exited {proc.returncode} after SIGTERM; stderr:\n{err}"
    done = {p.parent for p in out.glob("*/seed*/summary.json")}
    assert 2 <= len(done) < 8
    assert not list(out.glob("*/.*partial*"))  # the killed run cleaned up after itself
    stamps = _timestamps(out)

    rerun = []
    real = sweep_mod.run_job
    monkeypatch.setattr(
        sweep_mod, "run_job", lambda job: (rerun.append(Path(job.out)), real(job))[1]
    )
    from geosyn.experiments.cli import main

    assert main(args) == 0
    assert sorted(rerun) == sorted({out / p for p in _timestamps(out)} - done)
    assert len(_timestamps(out)) == 8
    for run, stamp in stamps.items():
        assert _timestamps(out)[run] == stamp
    assert os.path.isfile(out / "sweep_summary.md")
