"""Recorded trajectories (NPZ, CSV, Parquet) read back as PGA demonstrations."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from geosyn.synergies import pca_synergies
from geosyn.synergies.demonstrations import load_demonstrations, write_demonstrations
from geosyn.synergies.errors import InvalidSynergyInput


def test_npz_and_csv_round_trip(tmp_path) -> None:
    rng = np.random.default_rng(2)
    a, b = rng.normal(size=(20, 3)), rng.normal(size=(15, 3))
    np.savez(tmp_path / "d.npz", t=np.arange(20.0), a=a, b=b)
    got = load_demonstrations(tmp_path / "d.npz")
    assert [x.shape for x in got] == [(20, 3), (15, 3)]
    np.testing.assert_array_equal(got[0], a)
    np.testing.assert_array_equal(load_demonstrations(tmp_path / "d.npz", key="b")[0], b)
    # a geosyn run CSV: comments, t, q[<joint>] among other columns
    names = ["j1", "j2", "j3"]
    header = ["t", *(f"q[{n}]" for n in names), *(f"v[{n}]" for n in names)]
    rows = np.column_stack([np.arange(20.0), a, -a])
    with (tmp_path / "run.csv").open("w") as f:
        f.write("# run: x\n" + ",".join(header) + "\n")
        np.savetxt(f, rows, delimiter=",", fmt="%.17g")
    np.testing.assert_array_equal(load_demonstrations(tmp_path / "run.csv", names)[0], a)
    np.testing.assert_array_equal(load_demonstrations(tmp_path / "run.csv")[0], a)
    reordered = load_demonstrations(tmp_path / "run.csv", ["j3", "j1", "j2"])[0]
    np.testing.assert_array_equal(reordered, a[:, [2, 0, 1]])
    # a trajectory column splits the rows; PCA of the file equals PCA of the arrays
    ids = np.r_[np.zeros(20), np.ones(15)]
    with (tmp_path / "many.csv").open("w") as f:
        f.write("trajectory,j1,j2,j3\n")
        np.savetxt(f, np.column_stack([ids, np.vstack([a, b])]), delimiter=",", fmt="%.17g")
    got = load_demonstrations(tmp_path / "many.csv", names)
    assert [x.shape for x in got] == [(20, 3), (15, 3)]
    ref = pca_synergies(np.vstack([a, b]), 2)
    np.testing.assert_allclose(pca_synergies(got, 2).components, ref.components, atol=1e-12)


def test_bad_files_are_named(tmp_path) -> None:
    with pytest.raises(InvalidSynergyInput, match="does not exist"):
        load_demonstrations(tmp_path / "none.npz")
    (tmp_path / "x.txt").write_text("1,2\n")
    with pytest.raises(InvalidSynergyInput, match="allowed: .npz, .csv"):
        load_demonstrations(tmp_path / "x.txt")
    (tmp_path / "c.csv").write_text("t,q[a]\n0,1\n")
    with pytest.raises(InvalidSynergyInput, match="no column 'q\\[b\\]'"):
        load_demonstrations(tmp_path / "c.csv", ["b"])
    (tmp_path / "n.csv").write_text("a,b\n0,nan\n")
    with pytest.raises(InvalidSynergyInput, match="non-finite"):
        load_demonstrations(tmp_path / "n.csv")
    np.savez(tmp_path / "k.npz", a=np.zeros((3, 2)))
    with pytest.raises(InvalidSynergyInput, match="no array 'z'"):
        load_demonstrations(tmp_path / "k.npz", key="z")


def test_yaml_pga_synergies_from_recorded_demonstrations(tmp_path) -> None:
    """``synergies: {type: pga, demonstrations: FILE}`` gives PGA of the file's postures."""
    from pydantic import ValidationError

    from geosyn.experiments import schema as S
    from geosyn.experiments.run.build import build_metric, build_robot, build_synergies
    from geosyn.synergies import pga

    rng = np.random.default_rng(9)
    trajs = [np.cumsum(rng.normal(0, 0.05, (25, 2)), axis=0) + [0.3, 0.8] for _ in range(2)]
    np.savez(tmp_path / "demos.npz", a=trajs[0], b=trajs[1])
    base = {"name": "x", "kind": "synergy_combinations", "robot": {"name": "planar2"}}
    syn = {"type": "pga", "k": 1, "demonstrations": str(tmp_path / "demos.npz")}
    cfg = S.ExperimentConfig.model_validate({**base, "synergies": syn}, context={"nv": 2})
    robot = build_robot(cfg)
    metric = build_metric(cfg, robot)
    (synergy,) = build_synergies(cfg, metric, robot)
    ref = pga(metric, trajs, 1)  # the library call on the arrays themselves
    np.testing.assert_allclose(synergy.q0, ref.mean, atol=1e-12)
    np.testing.assert_allclose(synergy.v0, ref.V[:, 0], atol=1e-12)
    for bad in ({**syn, "q0": [0.0, 0.0]}, {"type": "pga", "k": 1}):
        with pytest.raises(ValidationError, match="exactly one of q0"):
            S.ExperimentConfig.model_validate({**base, "synergies": bad}, context={"nv": 2})


def test_written_files_read_back_unchanged(tmp_path) -> None:
    """write_demonstrations -> load_demonstrations is the identity (float64) for NPZ and
    CSV, and the CSV's columns are the named ones of the module doc."""
    rng = np.random.default_rng(4)
    trajs = [rng.normal(size=(n, 3)) for n in (7, 12, 5, 9, 3, 4, 6, 8, 2, 5, 11)]
    names = ["a", "b", "c"]
    for suffix in (".npz", ".csv"):
        path = write_demonstrations(tmp_path / f"d{suffix}", trajs, names)
        got = load_demonstrations(path, names if suffix == ".csv" else None)
        assert len(got) == len(trajs)  # 11 arrays: key order keeps trajectory order
        for x, y in zip(got, trajs, strict=True):
            np.testing.assert_array_equal(x, y)
    header = (tmp_path / "d.csv").read_text().splitlines()[0]
    assert header == "trajectory,q[a],q[b],q[c]"
    with pytest.raises(InvalidSynergyInput, match="allowed: .npz, .csv, .parquet"):
        write_demonstrations(tmp_path / "d.txt", trajs, names)
    with pytest.raises(InvalidSynergyInput, match="trajectories"):
        write_demonstrations(tmp_path / "d.csv", trajs, names[:2])


def test_parquet_without_pyarrow_names_the_extra(tmp_path, monkeypatch) -> None:
    """With pyarrow not importable, reading or writing Parquet raises geosyn's error
    naming the 'parquet' extra (runs whether pyarrow is installed or not)."""
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", None)
    (tmp_path / "d.parquet").write_bytes(b"PAR1")
    with pytest.raises(InvalidSynergyInput, match=r"geosyn\[parquet\]") as err:
        load_demonstrations(tmp_path / "d.parquet")
    assert isinstance(err.value.__cause__, ImportError)
    with pytest.raises(InvalidSynergyInput, match=r"geosyn\[parquet\]"):
        write_demonstrations(tmp_path / "e.parquet", [np.zeros((2, 1))], ["j"])


def test_parquet_round_trip_and_foreign_files(tmp_path) -> None:
    """Parquet (needs pyarrow, the 'parquet' extra): geosyn's own files read back
    unchanged, and a file written by pyarrow directly (string trajectory ids, a time
    column, joints under bare names and q[...] names) reads as its columns say."""
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    rng = np.random.default_rng(6)
    trajs = [rng.normal(size=(n, 2)) for n in (6, 4, 9)]
    path = write_demonstrations(tmp_path / "d.parquet", trajs, ["j1", "j2"])
    table = pq.read_table(path)
    assert table.column_names == ["trajectory", "q[j1]", "q[j2]"]
    for x, y in zip(load_demonstrations(path, ["j1", "j2"]), trajs, strict=True):
        np.testing.assert_array_equal(x, y)
    a, b = rng.normal(size=(5, 2)), rng.normal(size=(3, 2))
    rows = np.vstack([a, b])
    foreign = pa.table(
        {
            "t": np.arange(8.0),
            "trajectory": ["reach"] * 5 + ["lift"] * 3,
            "elbow": rows[:, 1],
            "q[shoulder]": rows[:, 0],
        }
    )
    pq.write_table(foreign, tmp_path / "f.parquet")
    got = load_demonstrations(tmp_path / "f.parquet", ["shoulder", "elbow"])
    np.testing.assert_array_equal(got[0], a)
    np.testing.assert_array_equal(got[1], b)
    with pytest.raises(InvalidSynergyInput, match="no column 'q\\[wrist\\]'"):
        load_demonstrations(tmp_path / "f.parquet", ["wrist"])
    (tmp_path / "bad.parquet").write_text("not parquet")
    with pytest.raises(InvalidSynergyInput, match="not a readable Parquet file"):
        load_demonstrations(tmp_path / "bad.parquet")


def test_yaml_pga_reads_a_parquet_file(tmp_path) -> None:
    """``synergies: {type: pga, demonstrations: FILE}`` with a .parquet file gives the
    synergies of the same trajectories given as .npz (needs pyarrow)."""
    pytest.importorskip("pyarrow")
    from geosyn.experiments import load_config
    from geosyn.experiments.run import build
    from geosyn.experiments.run.scene import build_robot

    rng = np.random.default_rng(8)
    q0 = np.array([0.3, 0.4, 0.0, -1.2, 0.0, 0.0, 0.0])
    trajs = [q0 + 0.05 * rng.normal(size=(6, 7)).cumsum(axis=0) for _ in range(3)]
    base, _ = load_config("arm_synergy_combinations", [])
    robot = build_robot(base)
    out = []
    for suffix in (".npz", ".parquet"):
        path = write_demonstrations(tmp_path / f"d{suffix}", trajs, robot.joint_names)
        data = base.model_dump()
        data["synergies"] = {"type": "pga", "demonstrations": str(path), "k": 2}
        cfg = type(base).model_validate(data)
        out.append(build.build_synergies(cfg, build.build_metric(cfg, robot), robot))
    assert len(out[1]) == 2
    for a, b in zip(*out, strict=True):
        np.testing.assert_allclose(a.q0, b.q0, atol=1e-12)
        np.testing.assert_allclose(a.v0, b.v0, atol=1e-12)
