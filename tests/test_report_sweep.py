"""``geosyn report`` on a sweep directory, and a failed sweep precondition."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from geosyn.core.errors import GeosynError
from geosyn.experiments.cli import main
from geosyn.experiments.sweep import sweep

CONFIG = {
    "name": "sw",
    "kind": "tracking",
    "robot": {"name": "planar2"},
    "reference": {"type": "log", "q_start": [0.2, 0.3], "goal": [0.8, 0.9], "duration": 0.3},
    "controllers": [{"type": "computed_torque", "kp": 400.0, "kd": 40.0}],
    "disturbances": [
        {"type": "push", "body": "link2", "force": [0.0, 5.0, 0.0], "start": 0.1, "duration": 0.05},
        {"type": "sensor_noise", "q_std": 0.0005},
    ],
    "simulation": {"duration": 0.3, "control_dt": 0.002},
    "outputs": {"plots": False, "csv": False},
}


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("sweep")
    cfg = root / "sw.yaml"
    cfg.write_text(yaml.safe_dump(CONFIG))
    out = root / "out"
    sweep(cfg, {"controllers.0.kp": ["100", "400"]}, seeds=2, out=out, progress=False)
    return out


def test_report_of_a_sweep_writes_tables_and_a_plot_per_axis(sweep_dir, capsys):
    for f in ("sweep_summary.json", "sweep_summary.md"):
        (sweep_dir / f).unlink()
    assert main(["report", str(sweep_dir)]) == 0
    printed = capsys.readouterr().out
    assert "computed_torque.rms_error [rad]" in printed  # units in the console table
    assert (sweep_dir / "sweep_controllers.0.kp.png").stat().st_size > 1000
    rows = json.loads((sweep_dir / "sweep_summary.json").read_text())
    assert [r["point"] for r in rows] == [
        {"controllers.0.kp": "100"},
        {"controllers.0.kp": "400"},
    ]
    # independent: the mean over seeds of the RMS error recomputed from each run's arrays
    for row in rows:
        point = f"controllers.0.kp={row['point']['controllers.0.kp']}"
        rms = []
        for seed in ("seed0", "seed1"):
            with np.load(sweep_dir / point / seed / "results.npz") as data:
                rms.append(np.sqrt(np.mean(data["computed_torque__tracking_error"] ** 2)))
        m = row["metrics"]["computed_torque.rms_error"]
        assert m["mean"] == pytest.approx(np.mean(rms), rel=1e-12)
        assert m["std"] == pytest.approx(np.std(rms), rel=1e-9, abs=1e-15)
    # the stiffer gain tracks better, and the seeds (sensor noise) really differ
    assert (
        rows[1]["metrics"]["computed_torque.rms_error"]["mean"]
        < rows[0]["metrics"]["computed_torque.rms_error"]["mean"]
    )
    assert rows[0]["metrics"]["computed_torque.rms_error"]["std"] > 0.0


def test_report_of_an_empty_directory_is_one_clear_error(tmp_path, capsys):
    assert main(["report", str(tmp_path)]) == 2
    assert "is it a run directory" in capsys.readouterr().err


def test_a_failed_sweep_precondition_leaves_no_directory(tmp_path):
    cfg = tmp_path / "sw.yaml"
    cfg.write_text(yaml.safe_dump(CONFIG))
    out = tmp_path / "never"
    with pytest.raises(GeosynError):  # no Ray head listens on port 1
        sweep(cfg, {"controllers.0.kp": ["100"]}, out=out, ray_address="127.0.0.1:1")
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sw.yaml"]
