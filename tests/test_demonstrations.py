"""Recorded trajectories (NPZ, CSV) read back as PGA demonstrations."""

from __future__ import annotations

import numpy as np
import pytest

from geosyn.synergies import pca_synergies
from geosyn.synergies.demonstrations import load_demonstrations
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
