"""Arrays that may be mapped from disk, read a block of rows at a time.

A long run's log (`geosyn.sim.log_spool`) is a read-only memory map of a file: the pages a
scan touches count in the process's resident memory (``RssFile``) until the kernel
reclaims them, so a scan of the whole log would hold the whole log in memory after all.
`row_blocks` scans in blocks of `SCAN_BLOCK` rows and `release`\\ s the mapped pages after
each block (``madvise(MADV_DONTNEED)``: the data stays in the page cache, not in the
process), and `save_npz` writes an ``.npz`` that way. For an in-memory array these are
plain numpy: `release` does nothing and one block of a short array is the whole array,
so a reduction over blocks gives the same bits as over the array.
"""

from __future__ import annotations

import mmap
import os
import zipfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

#: Rows read at a time by the block-by-block scans of a log (`row_blocks`); a scan holds
#: this many rows of the arrays it reads (4 MB for a 7-DoF arm's error and torques).
SCAN_BLOCK = 32_768


def mapping_of(array: Any) -> mmap.mmap | None:
    """The `mmap.mmap` an array's memory belongs to (walking its ``base`` chain), or None."""
    base = array
    while base is not None:
        if isinstance(base, mmap.mmap):
            return base
        base = base.obj if isinstance(base, memoryview) else getattr(base, "base", None)
    return None


def release(*arrays: Any) -> None:
    """Drop the resident pages of the file mappings behind ``arrays`` (none: no-op).

    The data stays readable: a later read faults it back in from the page cache. Costs
    O(mapped size / page size) in the kernel per mapping; each mapping is released once.
    """
    seen: set[int] = set()
    for a in arrays:
        mm = mapping_of(a)
        if mm is not None and id(mm) not in seen and not mm.closed:
            seen.add(id(mm))
            mm.madvise(mmap.MADV_DONTNEED)


def row_blocks(n_rows: int, *arrays: Any, size: int | None = None) -> Iterator[slice]:
    """Slices of at most ``size`` rows covering ``0 .. n_rows-1``, in order; the mapped
    pages of ``arrays`` are released after each block (`release`).

    Args:
        n_rows: rows to cover (the ``T`` of the arrays scanned).
        arrays: the arrays the caller reads in the loop.
        size: rows per block, >= 1; None: `SCAN_BLOCK`.
    """
    step = SCAN_BLOCK if size is None else size
    try:
        for start in range(0, n_rows, step):
            yield slice(start, min(start + step, n_rows))
            release(*arrays)
    finally:
        release(*arrays)


def save_npz(
    path: str | os.PathLike[str], arrays: Mapping[str, Any], compress: bool = True
) -> Path:
    """Write ``arrays`` to ``path`` as ``np.savez_compressed`` (``np.savez`` with
    ``compress=False``) does, each mapped array a block of rows at a time (`row_blocks`).

    The file reads back with `numpy.load` like numpy's own; in-memory arrays are written by
    numpy's own ``format.write_array``.

    Args:
        path: the ``.npz`` file (written as given, no suffix added).
        arrays: name -> array (no object arrays).

    Returns:
        The path written.
    """
    path = Path(path)
    method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with zipfile.ZipFile(path, mode="w", compression=method, allowZip64=True) as zf:
        for name, value in arrays.items():
            arr = np.asanyarray(value)
            with zf.open(f"{name}.npy", "w", force_zip64=True) as f:
                if mapping_of(arr) is None or arr.ndim == 0 or not arr.flags.c_contiguous:
                    np.lib.format.write_array(f, np.asarray(arr), allow_pickle=False)
                    continue
                header = np.lib.format.header_data_from_array_1_0(arr)
                np.lib.format.write_array_header_1_0(f, header)
                for rows in row_blocks(len(arr), arr):
                    f.write(arr[rows].tobytes())
    return path


__all__ = ["SCAN_BLOCK", "mapping_of", "release", "row_blocks", "save_npz"]
