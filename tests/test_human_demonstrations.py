"""Recorded trajectories (NPZ, CSV) read back as PGA demonstrations."""

from __future__ import annotations

import numpy as np
import pytest

from geosyn.synergies import pca_synergies
from geosyn.synergies.errors import InvalidSynergyInput
from geosyn.synergies.human.demonstrations import load_demonstrations


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
