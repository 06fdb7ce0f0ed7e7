"""Results never lost: run directories claimed atomically, no silent replacement, disk
full and read-only output end in one line, failed runs never summarised as perfect."""

from __future__ import annotations

import errno
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from geosyn.experiments import load_config, run_experiment
from geosyn.experiments.cli import main
from geosyn.experiments.errors import OutputNotWritable, RunDirectoryExists
from geosyn.experiments.results.summary import clean_summary
from geosyn.experiments.run import rundir

FAST = ["outputs.plots=false", "params.steps=100"]
SRC = "planar2_geodesic_vs_euclidean"


def _cfg(extra=()):
    cfg, _ = load_config(SRC, [*FAST, *extra])
    return cfg


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def test_two_concurrent_runs_to_one_out(tmp_path):
    """Exactly one succeeds, the other exits 2 with one line; the survivor is complete."""
    out = tmp_path / "run"
    sets = [a for s in [*FAST, "simulation.duration=1.0"] for a in ("--set", s)]
    cmd = [str(Path(sys.executable).with_name("geosyn")), "run", SRC, "--out", str(out)]
    procs = [
        subprocess.Popen(
            [*cmd, *sets, "--no-progress"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=tmp_path,
        )
        for _ in range(2)
    ]
    results = [(p.wait(timeout=300), *p.communicate()) for p in procs]
    codes = sorted(code for code, _, _ in results)
    assert codes == [0, 2], results
    (loser_err,) = [err for code, _, err in results if code == 2]
    assert "Traceback" not in loser_err and len(loser_err.strip().splitlines()) == 1
    assert "being written by another process" in loser_err or "already exists" in loser_err
    summary = json.loads((out / "summary.json").read_text())
    with np.load(out / "results.npz", allow_pickle=False) as r:
        tau = r["geodesic_computed_torque__tau_applied"]
    assert summary["geodesic.effort"] == pytest.approx(np.sum(tau**2) * 1e-3, rel=1e-12)
    assert _leftovers(tmp_path) == []  # no lock file, no partial directory


def test_force_never_replaces_a_directory_being_written(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    (out / "keep.txt").write_text("theirs")
    fd = rundir.acquire(out)  # another writer holds it (same effect across processes)
    try:
        with pytest.raises(RunDirectoryExists, match=r"being written by another process \(pid"):
            run_experiment(_cfg(), out, force=True, progress=False, quiet=True)
    finally:
        rundir.release(out, fd)
    assert (out / "keep.txt").read_text() == "theirs"
    assert _leftovers(tmp_path) == []
    # a stale lock file (its writer was killed) blocks nobody
    rundir.lock_path(out).write_text("999999\n")
    run_experiment(_cfg(), out, force=True, progress=False, quiet=True)
    assert (out / "summary.json").is_file() and not (out / "keep.txt").exists()
    assert _leftovers(tmp_path) == []


def test_lock_survives_a_release_race(tmp_path):
    """A writer that locked a lock file its previous holder removed locks the new one."""
    out = tmp_path / "run"
    fd = rundir.acquire(out)
    assert rundir.is_locked(out)
    rundir.release(out, fd)
    assert not rundir.is_locked(out) and not rundir.lock_path(out).exists()


@pytest.mark.parametrize("force", [False, True])
def test_out_pointing_at_a_file_is_refused(tmp_path, capsys, force):
    target = tmp_path / "notes.txt"
    target.write_text("mine")
    args = [
        "run",
        SRC,
        "--out",
        str(target),
        "--no-progress",
        *sum((["--set", s] for s in FAST), []),
    ]
    assert main([*args, *(["--force"] if force else [])]) == 2
    err = capsys.readouterr().err
    assert "RunDirectoryExists" in err and len(err.strip().splitlines()) == 1
    assert target.read_text() == "mine"
    inside = ["run", SRC, "--out", str(target / "run"), "--no-progress"]
    assert main(inside) == 2
    assert "a file, not a folder" in capsys.readouterr().err


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EROFS, errno.EACCES])
def test_disk_full_or_read_only_is_one_line(tmp_path, monkeypatch, capsys, code):
    import geosyn.experiments.run.runner as runner_mod

    def fail(*args, **kwargs):
        raise OSError(code, "simulated", str(tmp_path / "run" / "results.npz"))

    monkeypatch.setattr(runner_mod, "save_npz", fail)  # how the runner writes results.npz
    args = ["run", SRC, "--out", str(tmp_path / "run"), "--no-progress"]
    assert main([*args, *sum((["--set", s] for s in FAST), [])]) == 2
    err = capsys.readouterr().err
    assert "OutputNotWritable" in err and "choose another --out" in err
    assert len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []  # nothing half-written, no lock file


def test_unwritable_parent_is_one_error(tmp_path, monkeypatch):
    def fail(self, *args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system", str(self))

    monkeypatch.setattr(Path, "mkdir", fail)
    with pytest.raises(OutputNotWritable, match="Read-only file system"):
        run_experiment(_cfg(), tmp_path / "a" / "run", progress=False, quiet=True)


def test_failed_runs_are_not_summarised_as_perfect():
    summary = clean_summary(
        {
            "geodesic.ok": 0.0,
            "geodesic.rms_error": 0.0,
            "geodesic.recovery_time": 0.0,
            "geodesic.path_energy": 4.0,
            "geodesic.fallbacks": 3,
            "straight.ok": 1.0,
            "straight.rms_error": 0.01,
            "effort_ratio_straight_over_geodesic": 2.0,
        }
    )
    assert math.isnan(summary["geodesic.rms_error"])
    assert math.isnan(summary["geodesic.recovery_time"])
    assert math.isnan(summary["effort_ratio_straight_over_geodesic"])
    assert summary["geodesic.path_energy"] == 4.0  # a fact of the plan, not of the run
    assert math.isnan(summary["geodesic.fallbacks"])  # issue 23: counts of a failed run too
    assert summary["straight.rms_error"] == 0.01
    assert summary["failed_runs"] == 1.0
    assert "failed_runs" not in clean_summary({"energy": 1.0})


def test_diverged_run_reports_nan_and_its_cause(tmp_path, capsys):
    push = (
        "disturbances=[{type: push, body: link2, force: [1.0e7, 0, 0], start: 0.1, duration: 0.05}]"
    )
    outcome = run_experiment(_cfg([push]), tmp_path / "run", progress=False)
    s = outcome.summary
    assert s["failed_runs"] == 2.0
    for row in ("geodesic", "straight"):
        assert s[f"{row}.ok"] == 0.0
        assert math.isnan(s[f"{row}.rms_error"]) and math.isnan(s[f"{row}.recovery_time"])
        assert s[f"{row}.path_energy"] > 0
    err = capsys.readouterr().err
    assert "2 run(s) did not complete" in err and "diverged" in err and "t=0.1" in err
