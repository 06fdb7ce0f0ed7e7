"""A long run's log spooled to disk in chunks (issue 23): the same bits as in memory, the
same files written from it, and no spool file left behind (after the run, when it raises,
when it fails). The chunk is forced to 7 ticks so that short seeded runs spool."""

from __future__ import annotations

import errno
import gc
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import get_metric, get_robot
from geosyn.controllers import ComputedTorque, GeodesicReference
from geosyn.core.errors import GeosynError, InvalidArgument
from geosyn.experiments import run_experiment
from geosyn.experiments.config.loader import validate_config
from geosyn.experiments.results.data import write_csv
from geosyn.experiments.run.build import sim_arrays
from geosyn.experiments.run.run_metrics import disturbance_windows, standard_metrics
from geosyn.sim import (
    PayloadChange,
    SensorNoise,
    SimResult,
    Simulation,
    SpoolError,
    TorqueNoise,
    log_spool,
    spool_directory,
)
from geosyn.sim.blocks import mapping_of
from geosyn.sim.log import ARRAY_FIELDS
from geosyn.synergies.synergy import GeodesicSynergy
from geosyn.world import Payload, Sphere

#: Every array but the controller's wall time, which no two runs share.
_SAME = tuple(f for f in ARRAY_FIELDS if f != "compute_time")


def _sim(name: str) -> tuple[Simulation, np.ndarray]:
    robot = get_robot(name)
    q0 = np.array([0.3, -0.4]) if robot.nq == 2 else np.asarray(robot.neutral(), dtype=float)
    direction = np.linspace(0.4, -0.3, robot.nq)
    ref = GeodesicReference(GeodesicSynergy(get_metric(name), q0, direction))
    ct = ComputedTorque(robot, 400.0, 40.0, reference=ref)
    noise = [SensorNoise(q_std=1e-4, v_std=1e-3), TorqueNoise(std=0.5)]
    if name != "planar2":
        return Simulation(robot, ct, control_dt=1e-3, disturbances=noise, seed=3), q0
    # planar2 also logs a payload (its mass changing) and a clearance
    world = {"payloads": [Payload("tip", 0.3)], "obstacles": [Sphere((1.5, 1.5, 0.0), 0.1)]}
    noise.append(PayloadChange(0.05, 0.6))
    return Simulation(robot, ct, control_dt=1e-3, disturbances=noise, seed=3, **world), q0


def _assert_same(a: SimResult, b: SimResult) -> None:
    for name in _SAME:
        x, y = np.asarray(getattr(a, name)), np.asarray(getattr(b, name))
        assert (x.dtype, x.shape) == (y.dtype, y.shape), name
        assert x.tobytes() == y.tobytes(), f"{name} differs"


@pytest.mark.parametrize("name", ["planar2", "panda"])
def test_spooled_run_is_bit_identical_and_writes_the_same_files(name, tmp_path, monkeypatch):
    """Chunks of 7 ticks: every array (derived ones included: the effort's running sum is
    carried over), the summaries, the standard metrics, the saved .npz and the CSV."""
    sim, q0 = _sim(name)
    memory = sim.run(q0, None, 0.1)
    monkeypatch.setattr(log_spool, "SPOOL_CHUNK", 7)
    spooled = sim.run(q0, None, 0.1, spool_dir=tmp_path)
    assert memory.ok and spooled.ok and spooled.n_ticks == 100
    assert not memory.spooled and spooled.spooled
    if name == "planar2":  # the payload's region of the spool file, and a finite clearance
        assert set(spooled.payload_mass[:, 0]) == {0.3, 0.6}
        assert np.isfinite(spooled.clearance).all()
    assert not spooled.q.flags.writeable and mapping_of(spooled.tracking_error) is not None
    _assert_same(memory, spooled)
    assert spooled.rms_error() == memory.rms_error()
    assert spooled.rms_error(0.02, 0.05) == memory.rms_error(0.02, 0.05)
    assert spooled.saturation_count() == memory.saturation_count()
    assert spooled.total_effort == memory.total_effort
    metrics = [standard_metrics(r, 1e-3, disturbance_windows([])) for r in (memory, spooled)]
    assert [m.pop("wall_time") > 0 for m in metrics] == [True, True]
    assert metrics[0] == metrics[1]

    loaded = [
        SimResult.load(r.save(tmp_path / f"{i}.npz")) for i, r in enumerate((memory, spooled))
    ]
    _assert_same(*loaded)
    csv = []
    for i, res in enumerate((memory, spooled)):
        (tmp_path / f"run{i}").mkdir()
        (path,) = write_csv(tmp_path / f"run{i}", ["ct"], sim_arrays("ct", res))
        csv.append(path.read_bytes())
    assert csv[0] == csv[1]


_EXPERIMENT = {
    "name": "spooled",
    "kind": "tracking",
    "robot": {"name": "planar2"},
    "reference": {"type": "log", "q_start": [0.2, 0.3], "goal": [0.9, 1.1], "duration": 0.3},
    "controllers": [{"type": "computed_torque", "kp": 400.0, "kd": 40.0}],
    "disturbances": [
        {"type": "push", "body": "link2", "force": [0, 5, 0], "start": 0.1, "duration": 0.05}
    ],
    "simulation": {"duration": 0.4, "control_dt": 0.002},
    "outputs": {"plots": False, "parquet": True},
}


def test_an_experiment_spooled_into_its_run_directory_writes_the_same_results(
    tmp_path, monkeypatch
):
    """``geosyn run``'s path (results.npz, CSV, Parquet, summary) with chunks of 7 ticks:
    the same files as in memory, and the run directory holds no spool file."""
    import pyarrow.parquet as pq

    cfg = validate_config(_EXPERIMENT)
    plain = run_experiment(cfg, tmp_path / "plain", progress=False, quiet=True).path
    monkeypatch.setattr(log_spool, "SPOOL_CHUNK", 7)
    spooled = run_experiment(cfg, tmp_path / "spooled", progress=False, quiet=True).path
    csv = "data/computed_torque.csv"
    assert (plain / csv).read_bytes() == (spooled / csv).read_bytes()
    with np.load(plain / "results.npz") as a, np.load(spooled / "results.npz") as b:
        assert a.files == b.files
        for key in a.files:
            if "wall_time" not in key and not key.endswith("__meta"):
                assert a[key].tobytes() == b[key].tobytes(), key
    parquet = [pq.read_table(d / "data/computed_torque.parquet") for d in (plain, spooled)]
    assert parquet[0].equals(parquet[1])
    summaries = [json.loads((d / "summary.json").read_text()) for d in (plain, spooled)]
    for s in summaries:
        s.pop("computed_torque.wall_time")
    assert summaries[0] == summaries[1]
    assert not list(spooled.rglob("*.spool")) and not list(tmp_path.glob(".*"))


class _Stops:
    """Computed torque that raises ``error`` at tick ``at`` (and lists the spool
    directory on the tick before: the run's file is there while it runs)."""

    def __init__(self, inner: ComputedTorque, at: int, error: Exception, folder: Path) -> None:
        self.inner, self.at, self.error, self.folder = inner, at, error, folder
        self.seen: list[str] = []
        self.tick = 0

    def reset(self, q, v, t=0.0):
        self.tick = 0
        self.inner.reset(q, v, t)

    def compute(self, t, q, v):
        self.tick += 1
        if self.tick == self.at - 1:
            self.seen = sorted(p.name for p in self.folder.iterdir())
        if self.tick == self.at:
            raise self.error
        return self.inner.compute(t, q, v)


def _stopping(tmp_path: Path, error: Exception) -> tuple[Simulation, _Stops, np.ndarray]:
    sim, q0 = _sim("planar2")
    ctrl = _Stops(sim.controller, 30, error, tmp_path)  # type: ignore[arg-type]
    return Simulation(sim.robot, ctrl, control_dt=1e-3), ctrl, q0


@pytest.mark.skipif(sys.platform != "linux", reason="reads /proc/self/maps")
def test_no_spool_file_is_left_after_the_run_and_its_blocks_go_with_the_result(
    tmp_path, monkeypatch
):
    """The file is unlinked when the run ends (the directory set by `spool_directory`
    is empty), and the mapping disappears when the result is garbage collected."""
    monkeypatch.setattr(log_spool, "SPOOL_CHUNK", 7)
    sim, ctrl, q0 = _stopping(tmp_path, RuntimeError("never"))
    ctrl.at = 10**9
    with spool_directory(tmp_path):
        res = sim.run(q0, None, 0.05)
    assert res.spooled and list(tmp_path.iterdir()) == []
    maps = Path("/proc/self/maps")
    assert str(tmp_path) in maps.read_text()  # (deleted): mapped until the result goes
    assert res.t[-1] == 0.049  # readable after its file was removed
    del res
    gc.collect()
    assert str(tmp_path) not in maps.read_text()


@pytest.mark.parametrize(
    "error", [InvalidArgument("bad input"), KeyboardInterrupt()], ids=["invalid", "interrupt"]
)
def test_a_run_that_raises_mid_run_leaves_no_spool_file(error, tmp_path, monkeypatch):
    monkeypatch.setattr(log_spool, "SPOOL_CHUNK", 7)
    sim, ctrl, q0 = _stopping(tmp_path, error)
    with pytest.raises(type(error)):
        sim.run(q0, None, 0.1, spool_dir=tmp_path)
    assert len(ctrl.seen) == 1 and ctrl.seen[0].endswith(".spool")  # it was spooling
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("at", [5, 30])
def test_a_failed_run_keeps_its_ticks_and_leaves_no_spool_file(at, tmp_path, monkeypatch):
    """A controller failure ends the run (status kept): 29 ticks (4 chunks written, then
    mapped), or 4 (within the first chunk: nothing written, the rows stay in memory)."""
    monkeypatch.setattr(log_spool, "SPOOL_CHUNK", 7)
    sim, ctrl, q0 = _stopping(tmp_path, GeosynError("solver gave up"))
    ctrl.at = at
    res = sim.run(q0, None, 0.1, spool_dir=tmp_path)
    assert res.status.startswith("controller failed") and res.n_ticks == at - 1
    assert res.spooled == (at > 7) and list(tmp_path.iterdir()) == []
    np.testing.assert_array_equal(res.t, np.arange(at - 1) * 1e-3)


def test_a_spool_directory_that_cannot_take_the_file_is_a_spool_error(tmp_path, monkeypatch):
    """Refused before the run starts, as a geosyn error that is also the OSError it was."""
    monkeypatch.setattr(log_spool, "SPOOL_CHUNK", 7)
    sim, q0 = _sim("planar2")
    with pytest.raises(SpoolError) as err:
        sim.run(q0, None, 0.1, spool_dir=tmp_path / "missing")
    assert isinstance(err.value, GeosynError) and isinstance(err.value, OSError)
    assert err.value.errno == errno.ENOENT and str(tmp_path / "missing") in str(err.value)
