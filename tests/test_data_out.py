"""Data out: per-run CSV with named columns, one loader for SimResult and experiment
files, the tidy table, run.json provenance, the run log."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

import geosyn
from geosyn.core.errors import InvalidArgument
from geosyn.experiments import run_experiment
from geosyn.experiments.config.loader import validate_config
from geosyn.experiments.results.data import load_runs, load_table
from geosyn.sim import SimResult
from geosyn.sim.log import saved_runs

JOINTS = ("joint1", "joint2")


def _config(**outputs):
    return validate_config(
        {
            "name": "data_out",
            "kind": "tracking",
            "robot": {"name": "planar2"},
            "reference": {
                "type": "log",
                "q_start": [0.2, 0.3],
                "goal": [0.9, 1.1],
                "duration": 0.3,
                "steps": 40,
            },
            "controllers": [
                {"type": "computed_torque", "kp": 400.0, "kd": 40.0},
                {"type": "riemannian_pd", "label": "rpd"},
            ],
            "disturbances": [
                {
                    "type": "push",
                    "body": "link2",
                    "force": [0.0, 5.0, 0.0],
                    "start": 0.1,
                    "duration": 0.05,
                }
            ],
            "simulation": {"duration": 0.4, "control_dt": 0.002},
            "outputs": {"plots": False, **outputs},
        }
    )


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    return run_experiment(
        _config(), tmp_path_factory.mktemp("d") / "run", progress=False, quiet=True
    ).path


def test_joint_names_of_the_robot(run_dir):
    res = SimResult.load(run_dir / "results.npz", "rpd")
    from geosyn.robots import load_robot

    assert res.joint_names == tuple(load_robot("planar2").joint_names) == JOINTS


def test_csv_has_named_columns_and_exact_values(run_dir):
    path = run_dir / "data" / "computed_torque.csv"
    lines = path.read_text().splitlines()
    comments = {ln[2:].split(": ")[0]: ln.split(": ", 1)[1] for ln in lines if ln.startswith("#")}
    assert comments["controller"] == "computed_torque" and comments["status"] == "ok"
    header = lines[len(comments)].split(",")
    assert header[:3] == ["t", "q[joint1]", "q[joint2]"]
    for col in ("v[joint2]", "q_ref[joint1]", "tau_applied[joint2]", "clearance", "effort"):
        assert col in header
    table = np.loadtxt(path, delimiter=",", comments="#", skiprows=len(comments) + 1)
    with np.load(run_dir / "results.npz") as data:
        q, tau, t = (
            data["computed_torque__q"],
            data["computed_torque__tau_applied"],
            data["computed_torque__t"],
        )
    # %.17g round-trips float64 exactly
    np.testing.assert_array_equal(table[:, 0], t)
    np.testing.assert_array_equal(table[:, header.index("q[joint2]")], q[:, 1])
    np.testing.assert_array_equal(table[:, header.index("tau_applied[joint1]")], tau[:, 0])


def test_simresult_load_reads_an_experiment_file(run_dir, tmp_path):
    path = run_dir / "results.npz"
    assert saved_runs(path) == ["computed_torque", "rpd"]
    res = SimResult.load(path, "computed_torque")
    with np.load(path) as data:
        np.testing.assert_array_equal(res.q, data["computed_torque__q"])
        np.testing.assert_array_equal(res.tracking_error, data["computed_torque__tracking_error"])
    assert res.control_dt == 0.002 and res.robot_name == "planar2" and res.ok
    assert np.isnan(res.q_meas).all()  # not kept by experiments: NaN, never made up
    # its metrics are those the run reported
    assert res.total_effort == pytest.approx(
        json.loads((run_dir / "summary.json").read_text())["computed_torque.effort"], rel=1e-12
    )
    with pytest.raises(InvalidArgument, match="which run.*computed_torque, rpd"):
        SimResult.load(path)
    with pytest.raises(InvalidArgument, match="run 'mpc' is not in it"):
        SimResult.load(path, "mpc")
    # a SimResult saved by itself still loads, and an experiment run saves and reloads
    again = res.save(tmp_path / "one.npz")
    np.testing.assert_array_equal(SimResult.load(again).q, res.q)
    assert set(load_runs(run_dir)) == {"computed_torque", "rpd"}


def test_tidy_table(run_dir):
    df = load_table(run_dir)
    T = len(SimResult.load(run_dir / "results.npz", "rpd").t)
    assert len(df) == 2 * T * 2  # runs x ticks x joints
    assert set(df["controller"]) == {"computed_torque", "rpd"}
    assert set(df["joint"]) == set(JOINTS)
    row = df[(df.run == "rpd") & (df.joint == "joint2")]
    with np.load(run_dir / "results.npz") as data:
        np.testing.assert_array_equal(row["q"].to_numpy(), data["rpd__q"][:, 1])
        np.testing.assert_array_equal(row["t"].to_numpy(), data["rpd__t"])
    # a tidy table answers questions by grouping: RMS error per controller
    rms = df.groupby("controller")["tracking_error"].apply(lambda e: np.sqrt(np.mean(e**2)))
    summary = json.loads((run_dir / "summary.json").read_text())
    assert rms["rpd"] == pytest.approx(summary["rpd.rms_error"], rel=1e-12)


def test_run_json_has_version_and_commit_and_the_log_says_what_happened(run_dir):
    meta = json.loads((run_dir / "run.json").read_text())
    assert meta["geosyn"] == geosyn.__version__
    root = Path(geosyn.__file__).resolve().parent.parent
    head = subprocess.run(
        ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, check=False
    )
    if head.returncode == 0:
        assert meta["git"]["commit"] == head.stdout.strip()
        assert isinstance(meta["git"]["dirty"], bool)
    else:  # not a checkout: said so, not made up
        assert meta["git"]["commit"] is None
    log = (run_dir / "run.log").read_text()
    assert "closed-loop run computed_torque: ok" in log
    assert "closed-loop run rpd: ok" in log
    assert "wrote data/rpd.csv" in log and "finished in" in log


def test_csv_can_be_turned_off(tmp_path):
    out = run_experiment(_config(csv=False), tmp_path / "r", progress=False, quiet=True).path
    assert not (out / "data").exists()


def test_a_missing_video_package_keeps_the_finished_run(tmp_path, monkeypatch):
    from geosyn.sim import Clip

    def missing(*args, **kwargs):
        raise ImportError("No module named 'imageio'")  # as without the video extra

    monkeypatch.setattr(Clip, "save", missing)
    cfg = _config(fps=5.0, width=64, height=48)
    out = run_experiment(cfg, tmp_path / "v", video=True, progress=False, quiet=True).path
    assert (out / "summary.json").is_file() and (out / "data" / "rpd.csv").is_file()
    assert not list(out.glob("video_*"))
    meta = json.loads((out / "run.json").read_text())
    assert "imageio" in meta["video"]["error"]  # said why, not silently skipped
    assert "imageio" in (out / "run.log").read_text()


def test_outputs_parquet_writes_each_run_as_the_csv_reads(tmp_path):
    """``outputs.parquet: true``: data/<run>.parquet beside the CSV, the same columns and
    values (referees: pandas' CSV reader and pyarrow's Parquet reader)."""
    import pandas as pd
    import pyarrow.parquet as pq

    out = run_experiment(_config(parquet=True), tmp_path / "run", progress=False, quiet=True).path
    csvs = sorted((out / "data").glob("*.csv"))
    assert len(csvs) == 2
    for csv in csvs:
        table = pq.read_table(csv.with_suffix(".parquet")).to_pandas()
        frame = pd.read_csv(csv, comment="#")
        assert list(table.columns) == list(frame.columns)
        np.testing.assert_allclose(table.to_numpy(), frame.to_numpy(), rtol=1e-12, atol=0)
    assert (
        "wrote data/" in (out / "run.log").read_text()
        and ".parquet" in (out / "run.log").read_text()
    )


def test_outputs_parquet_without_pyarrow_is_refused_naming_the_extra(monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util,
        "find_spec",
        lambda name, *a, **k: None if name == "pyarrow" else real(name, *a, **k),
    )
    with pytest.raises(
        geosyn.core.errors.GeosynError, match=r"outputs\.parquet.*geosyn\[parquet\]"
    ):
        _config(parquet=True)


def test_controller_notes_reach_the_run_log_and_the_saved_result(tmp_path):
    """What a controller notes (here: computed torque compensating the file's damping and
    dry friction) is written to run.log per run and kept with the run's SimResult."""
    import mujoco

    from geosyn.sim import SimResult

    fixture = Path(__file__).parent / "fixtures" / "arm_root_quat.xml"
    q0 = [0.3, 0.2, -0.2, 0.05, 0.3]
    data = {
        "name": "notes",
        "kind": "tracking",
        "robot": {"name": str(fixture)},
        "reference": {"type": "log", "q_start": q0, "goal": [x + 0.1 for x in q0],
                      "duration": 0.1, "steps": 20},
        "controllers": [{"type": "computed_torque", "label": "ct"}],
        "simulation": {"duration": 0.1, "control_dt": 0.002},
        "outputs": {"plots": False, "csv": False},
    }  # fmt: skip
    out = run_experiment(validate_config(data), tmp_path / "run", progress=False, quiet=True)
    log = (out.path / "run.log").read_text()
    res = SimResult.load(out.path / "results.npz", "ct")
    # the referee: MuJoCo's own compile of the file states the dry friction noted
    friction = mujoco.MjModel.from_xml_path(str(fixture)).dof_frictionloss
    assert np.any(friction > 0)
    (note,) = [n for n in res.controller_notes if n.startswith("compensate_friction: ")]
    for value in friction[friction > 0]:
        assert repr(float(value)) in note, note
    for n in res.controller_notes:
        assert f"closed-loop run ct: controller note {n}" in log
