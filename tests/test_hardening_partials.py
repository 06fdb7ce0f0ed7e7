"""Partial run directories of dead writers never stay (issue 23): a run killed with
``kill -9`` leaves ``.<out>.partial-*`` (and its lock file); the next run in that folder
or ``geosyn clean`` removes them, and never those of a live writer
(`geosyn.experiments.run.rundir`)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from geosyn.experiments.cli import main

SRC = "planar2_geodesic_vs_euclidean"
FAST = ["outputs.plots=false", "params.steps=100"]
#: a run that lasts minutes: it is killed long before it ends
LONG = [*FAST, "simulation.duration=300.0", "params.duration=300.0"]

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="kill -9, flock")


def _start(folder: Path, out: str) -> subprocess.Popen[str]:
    sets = [a for s in LONG for a in ("--set", s)]
    return subprocess.Popen(
        [str(Path(sys.executable).with_name("geosyn")), "run", SRC, "--out", out, *sets,
         "--no-progress"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        cwd=folder,
    )  # fmt: skip


def _wait_for_partial(folder: Path, out: str, proc: subprocess.Popen[str]) -> Path:
    deadline = time.monotonic() + 120.0  # a hang guard: the partial appears in seconds
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        found = list(folder.glob(f".{out}.partial-*/run.log"))
        if found:
            return found[0].parent
        time.sleep(0.05)
    raise AssertionError("the run never created its partial directory")


def _hidden(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def _killed_run(folder: Path, out: str) -> Path:
    """A run of ``out`` killed with SIGKILL while it simulates; returns its partial."""
    proc = _start(folder, out)
    partial = _wait_for_partial(folder, out, proc)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    assert proc.returncode == -signal.SIGKILL
    assert partial.is_dir()  # what the issue found: kill -9 leaves it
    return partial


def test_a_later_run_removes_a_killed_runs_partial(tmp_path: Path) -> None:
    """Same --out, then another --out in the same folder: both clean the dead partials."""
    first = _killed_run(tmp_path, "a")
    assert (tmp_path / ".a.lock").exists()
    assert main(["run", SRC, "--out", str(tmp_path / "a"), *(a for s in FAST for a in ("--set", s)),
                 "--no-progress"]) == 0  # fmt: skip
    assert not first.exists() and (tmp_path / "a" / "summary.json").is_file()
    assert _hidden(tmp_path) == []
    second = _killed_run(tmp_path, "b")
    assert main(["run", SRC, "--out", str(tmp_path / "c"), *(a for s in FAST for a in ("--set", s)),
                 "--no-progress"]) == 0  # fmt: skip
    assert not second.exists()
    assert _hidden(tmp_path) == []  # its lock file too (taken and released)


@pytest.mark.slow  # ~5-9 s: two runs in subprocesses
def test_geosyn_clean_keeps_a_live_writer(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A killed run's partial and lock are removed, a running one's partial is kept (the
    live run started first: a run that starts later cleans its folder itself)."""
    live = _start(tmp_path, "live")
    try:
        live_partial = _wait_for_partial(tmp_path, "live", live)
        dead = _killed_run(tmp_path, "dead")
        assert live_partial.is_dir()
        assert main(["clean", str(tmp_path)]) == 0
        out = capsys.readouterr().out
        assert not dead.exists() and not (tmp_path / ".dead.lock").exists()
        assert live_partial.is_dir() and (tmp_path / ".live.lock").exists()
        assert f"kept {live_partial}" in out and "2 removed, 1 kept" in out
    finally:
        live.send_signal(signal.SIGTERM)
        live.communicate(timeout=60)
    assert live.returncode == 143
    assert _hidden(tmp_path) == []
