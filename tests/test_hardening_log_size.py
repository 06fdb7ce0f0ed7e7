"""A long run's memory and disk are what `log_size` says (issue 23): a run longer than
``SPOOL_CHUNK`` ticks holds one chunk of rows in memory and spools the rest to disk, and
every output is written from it a block at a time, so memory does not grow with the run:
a 600 s run at the default log rate (every 1 ms tick) peaks within 40 MB of a 20 s one
and under 500 MB, measured by the kernel (``getrusage``) in child processes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import get_metric, get_robot
from geosyn.controllers import ComputedTorque, GeodesicReference
from geosyn.experiments.results import data
from geosyn.experiments.results.data import log_size, write_csv
from geosyn.sim import Simulation
from geosyn.sim.log import LOG_FIELDS
from geosyn.sim.log_spool import SPOOL_CHUNK
from geosyn.synergies.synergy import GeodesicSynergy

_MEASURE = """
import resource, subprocess, sys
subprocess.run(sys.argv[1:], check=True, stdout=subprocess.DEVNULL)
print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024)
"""

_CONFIG = """\
name: long_run
kind: tracking
robot:
  name: planar2
reference:
  type: log
  q_start: [0.3, -0.4]
  goal: [0.7, 0.0]
  duration: 1.0
  steps: 50
controllers:
  - type: computed_torque
simulation:
  duration: {duration}
  control_dt: 0.001
"""


def _run_50_ticks():
    robot, q0 = get_robot("planar2"), np.array([0.3, -0.4])
    ref = GeodesicReference(GeodesicSynergy(get_metric("planar2"), q0, np.array([0.4, 0.4])))
    ct = ComputedTorque(robot, 400.0, 40.0, reference=ref)
    res = Simulation(robot, ct, control_dt=1e-3).run(q0, np.zeros(2), 0.05)
    assert res.ok and res.n_ticks == 50
    return robot, res


def test_log_size_is_the_simulations_rows() -> None:
    """Against the arrays a simulation returns (their nbytes, tick and derived fields)."""
    robot, res = _run_50_ticks()
    per_run = sum(
        np.asarray(getattr(res, f.name)).nbytes
        for f in LOG_FIELDS
        if f.source in ("tick", "derived")
    )
    size = log_size(robot.nq, robot.nv, 0, res.n_ticks)
    assert size.memory == per_run == 219 * res.n_ticks and size.spool == 0
    long = log_size(7, 7, 0, 10**6)  # a 7-DoF arm at the tick limit: one chunk in memory
    assert long.memory == 584 * SPOOL_CHUNK and long.spool == 584 * 10**6


def test_csv_is_within_its_estimate_and_reads_back(tmp_path: Path) -> None:
    """Written in blocks of CSV_BLOCK rows (here forced to 7): the same numbers."""
    _, res = _run_50_ticks()
    from geosyn.experiments.run.build import sim_arrays

    arrays = sim_arrays("ct", res)
    old = data.CSV_BLOCK
    data.CSV_BLOCK = 7
    try:
        (path,) = write_csv(tmp_path, ["ct"], arrays)
    finally:
        data.CSV_BLOCK = old
    table = np.loadtxt(path, delimiter=",", comments="#", skiprows=6)
    assert table.shape == (res.n_ticks, 19)
    np.testing.assert_array_equal(table[:, 0], res.t)
    np.testing.assert_array_equal(table[:, 1:3], res.q)  # %.17g round-trips float64
    body = path.stat().st_size - sum(len(x) + 1 for x in path.read_text().splitlines()[:6])
    assert body <= log_size(2, 2, 0, res.n_ticks).csv


@pytest.mark.slow
def test_600_s_run_memory_does_not_grow_with_its_length(tmp_path: Path) -> None:
    """600 s at 1 kHz (600,000 ticks, every tick logged) against 20 s (20,000: also
    spooled), default outputs (CSV, plots): peak RSS < 500 MB (measured 270 MB; 394 MB
    before spooling, without plots) and within 40 MB of the 20 s run's (measured +4 MB,
    266 -> 270 MB; the log alone would be +127 MB)."""
    peaks = {}
    for duration in (20.0, 600.0):
        config = tmp_path / f"run{duration:g}.yaml"
        config.write_text(_CONFIG.format(duration=duration))
        out = tmp_path / f"out{duration:g}"
        geosyn = str(Path(sys.executable).with_name("geosyn"))
        cmd = [sys.executable, "-c", _MEASURE, geosyn, "run", str(config), "--out", str(out)]
        done = subprocess.run([*cmd, "--no-progress"], capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
        peaks[duration] = int(done.stdout.split()[-1])
        assert json.loads((out / "summary.json").read_text())["computed_torque.ok"] == 1.0
        assert not list(out.rglob("*.spool"))  # the spool file went with the run
        assert (out / "tracking_error.png").is_file()
    assert peaks[600.0] < 500 * 2**20, f"peak RSS {peaks[600.0] / 2**20:.0f} MB"
    growth = peaks[600.0] - peaks[20.0]
    assert growth < 40 * 2**20, f"600 s run peaks {growth / 2**20:.0f} MB above the 20 s one"
    assert log_size(2, 2, 0, 580_000).spool > 3 * 40 * 2**20  # what growth would have been
    csv = tmp_path / "out600" / "data" / "computed_torque.csv"
    assert csv.stat().st_size < log_size(2, 2, 0, 600_000).csv
