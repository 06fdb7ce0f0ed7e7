"""Data out as Parquet: data/<run>.parquet has the CSV's named columns and values
(pyarrow, the 'parquet' extra), and a clear error names the extra without it."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from geosyn.experiments import run_experiment
from geosyn.experiments.config.loader import validate_config
from geosyn.experiments.errors import ExperimentError
from geosyn.experiments.results.parquet import write_parquet


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    cfg = validate_config(
        {
            "name": "parquet_out",
            "kind": "tracking",
            "robot": {"name": "planar2"},
            "reference": {
                "type": "log",
                "q_start": [0.2, 0.3],
                "goal": [0.9, 1.1],
                "duration": 0.2,
                "steps": 20,
            },
            "controllers": [{"type": "computed_torque", "kp": 400.0, "kd": 40.0}],
            "simulation": {"duration": 0.2, "control_dt": 0.002},
            "outputs": {"plots": False},
        }
    )
    return run_experiment(
        cfg, tmp_path_factory.mktemp("p") / "run", progress=False, quiet=True
    ).path


def test_parquet_has_the_csv_columns_and_values(run_dir) -> None:
    pq = pytest.importorskip("pyarrow.parquet")
    (path,) = write_parquet(run_dir, ["computed_torque"])
    assert path == run_dir / "data" / "computed_torque.parquet"
    csv = run_dir / "data" / "computed_torque.csv"
    lines = csv.read_text().splitlines()
    comments = {ln[2:].split(": ")[0]: ln.split(": ", 1)[1] for ln in lines if ln.startswith("#")}
    header = lines[len(comments)].split(",")
    reference = np.loadtxt(csv, delimiter=",", comments="#", skiprows=len(comments) + 1)
    table = pq.read_table(path)
    assert table.column_names == header
    for j, name in enumerate(header):
        np.testing.assert_array_equal(table.column(name).to_numpy(), reference[:, j])
    meta = {k.decode(): v.decode() for k, v in table.schema.metadata.items()}
    assert meta == comments


def test_without_pyarrow_the_error_names_the_extra(run_dir, monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", None)
    with pytest.raises(ExperimentError, match=r"geosyn\[parquet\]") as err:
        write_parquet(run_dir, ["computed_torque"])
    assert isinstance(err.value.__cause__, ImportError)
