"""Arrays mapped from disk read a block at a time (`geosyn.sim.blocks`): a scan's pages
leave the process's resident memory when released (read from /proc/self/status), and an
.npz written a block at a time reads back as numpy's own."""

from __future__ import annotations

import mmap
import sys
from pathlib import Path

import numpy as np
import pytest

from geosyn.sim.blocks import mapping_of, release, row_blocks, save_npz


def _mapped(path: Path, array: np.ndarray) -> np.ndarray:
    array.tofile(path)
    with path.open("rb") as f:
        mm = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
    return np.frombuffer(mm, array.dtype).reshape(array.shape)


def _rss_file_kb() -> int:
    status = Path("/proc/self/status").read_text()
    return int(next(x for x in status.splitlines() if x.startswith("RssFile:")).split()[1])


@pytest.mark.skipif(sys.platform != "linux", reason="reads /proc/self/status")
def test_released_pages_leave_resident_memory(tmp_path):
    """Summing a 64 MB map makes it resident (RssFile); `release` gives it back, and a
    scan by `row_blocks` never holds more than about a block."""
    a = _mapped(tmp_path / "a.bin", np.arange(8 << 20, dtype=np.float64).reshape(-1, 4))
    assert mapping_of(a[10:, 1]) is not None and mapping_of(np.zeros(3)) is None
    before = _rss_file_kb()
    total = float(a.sum())
    assert _rss_file_kb() - before > 60_000  # kB: the whole map was read in
    release(a)
    assert _rss_file_kb() - before < 4_000
    peak, blocked = 0, 0.0
    for rows in row_blocks(len(a), a, size=65_536):  # 2 MB per block
        blocked += float(a[rows].sum())
        peak = max(peak, _rss_file_kb() - before)
    assert peak < 8_000 and _rss_file_kb() - before < 4_000
    assert blocked == pytest.approx(total, rel=1e-12)


def test_save_npz_writes_what_numpy_reads(tmp_path):
    data = np.random.default_rng(0).normal(size=(1000, 3))
    arrays = {
        "mapped": _mapped(tmp_path / "m.bin", data),
        "flags": _mapped(tmp_path / "f.bin", data[:, 0] > 0),
        "column": _mapped(tmp_path / "c.bin", data)[:, 1],  # not contiguous: numpy's writer
        "plain": np.arange(5),
        "text": np.array("ok"),
    }
    for compress in (True, False):
        path = save_npz(tmp_path / f"x{compress}.npz", arrays, compress=compress)
        with np.load(path) as back:
            assert back.files == list(arrays)
            for name, value in arrays.items():
                assert back[name].dtype == value.dtype and np.array_equal(back[name], value)
