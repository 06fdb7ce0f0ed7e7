"""The per-tick log of a run as it runs: in memory, or spooled to disk in chunks.

A run of at most `SPOOL_CHUNK` ticks (every test, most experiments) keeps its rows in
memory as before: `LogWriter` allocates them whole (`geosyn.sim.log.allocate_rows`) and
`finish` returns `geosyn.sim.log.finish_rows` of them. A longer run holds one chunk of
`SPOOL_CHUNK` rows in memory: each full chunk, with its derived fields
(`geosyn.sim.log.derive_rows`, the effort's running sum carried over), is written to one
spool file, and the buffers are reused. The file holds each tick and derived field of
`geosyn.sim.log.LOG_FIELDS` as a raw C-order array in native byte order (little-endian
on x86-64 and arm64) in its own page-aligned region sized for the planned ticks (a
sparse file: a run that stops early takes only the rows it wrote). When the run ends the
file is mapped read-only, the `SimResult` arrays are views of that map, and the file is
unlinked at once: nothing is left on disk, and the system frees its blocks when the last
array is garbage collected. A run that raises removes its file before the error
propagates; only a process killed mid-run leaves one, in the spool directory.

The spool file goes to the directory given to `geosyn.sim.Simulation.run`, else the one
set by `spool_directory` (``geosyn run`` sets its run directory, so that the cleanup of a
dead writer's partial directory covers it), else `tempfile`'s (``$TMPDIR``, ``/tmp``).
Memory: one chunk, ``SPOOL_CHUNK * row bytes`` (1.8 MB on planar2, 4.8 MB on a 7-DoF
arm); disk: the row bytes per tick (219 B on planar2, 584 B on a 7-DoF arm;
`geosyn.experiments.results.data.log_size`).
"""

from __future__ import annotations

import errno
import math
import mmap
import os
import shutil
import tempfile
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.sim.errors import SpoolError
from geosyn.sim.log import LOG_FIELDS, allocate_rows, derive_rows, finish_rows

#: Ticks per chunk of a spooled log; a run of at most this many ticks stays in memory
#: (8,192 ticks: 8.2 s at 1 kHz).
SPOOL_CHUNK = 8192

#: The tick and derived fields, in file order.
_SPOOLED = tuple(f for f in LOG_FIELDS if f.source in ("tick", "derived"))

_DIRECTORY: ContextVar[Path | None] = ContextVar("geosyn_spool_directory", default=None)


@contextmanager
def spool_directory(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Within the block, runs spool their logs into ``path`` unless given a directory.

    Restores the previous directory on exit (a context variable: threads and tasks see
    their own).
    """
    token = _DIRECTORY.set(Path(path))
    try:
        yield Path(path)
    finally:
        _DIRECTORY.reset(token)


def row_bytes(dims: Mapping[str, int]) -> int:
    """Bytes of one tick of the log: its tick and derived fields (see `LOG_FIELDS`).

    Args:
        dims: ``nq``, ``nv``, ``P`` (payloads).
    """
    return sum(_row_items(f.shape, dims) * np.dtype(f.dtype).itemsize for f in _SPOOLED)


def _row_items(shape: tuple[str, ...], dims: Mapping[str, int]) -> int:
    return math.prod(dims[d] for d in shape if d != "T")


class LogWriter:
    """The rows of one run being logged: in memory, or one chunk spooled at a time.

    The simulation writes tick ``k`` into row ``k - written`` of `rows` (row ``k`` when
    not spooled), calls `flush` when `chunk` rows are written, `finish` at the end and
    `discard` if the run raises. Allocates its buffers (and opens the file) here; `flush`
    allocates only the chunk's derived fields.

    Args:
        n_ticks: ticks planned.
        dims: ``nq``, ``nv``, ``P`` (payloads).
        control_dt: control period [s] (the effort integrates over it).
        directory: where the spool file goes (see the module doc); None: the default.
        chunk: ticks per chunk (`SPOOL_CHUNK` by default); runs of at most this many
            ticks are not spooled.

    Raises:
        SpoolError: the spool file cannot be created, or the directory has less free
            space than the planned log.
    """

    def __init__(
        self,
        n_ticks: int,
        dims: Mapping[str, int],
        control_dt: float,
        directory: str | os.PathLike[str] | None = None,
        chunk: int | None = None,
    ) -> None:
        size = SPOOL_CHUNK if chunk is None else int(chunk)
        self.spooled = n_ticks > size
        #: rows written before `flush` must be called (never reached when not spooled)
        self.chunk = size if self.spooled else n_ticks + 1
        self.control_dt = control_dt
        self.rows = allocate_rows(size if self.spooled else n_ticks, dims)
        #: ticks already in the spool file
        self.written = 0
        self.path: Path | None = None
        self._dims = dict(dims)
        self._fd = -1
        self._effort_sum = 0.0
        self._offsets: dict[str, int] = {}
        if self.spooled:
            self._open(n_ticks, directory)

    def _open(self, n_ticks: int, directory: str | os.PathLike[str] | None) -> None:
        folder = Path(directory) if directory is not None else _DIRECTORY.get()
        where = str(folder) if folder is not None else tempfile.gettempdir()
        offset = 0
        for f in _SPOOLED:
            nbytes = n_ticks * _row_items(f.shape, self._dims) * np.dtype(f.dtype).itemsize
            if nbytes:
                self._offsets[f.name] = offset
                offset += -(-nbytes // mmap.PAGESIZE) * mmap.PAGESIZE
        try:
            free = shutil.disk_usage(where).free
            if free < offset:
                raise SpoolError(
                    errno.ENOSPC,
                    f"a log of {n_ticks} ticks needs {offset / 2**20:.0f} MB on disk;"
                    f" {free / 2**20:.0f} MB free in the spool directory",
                    where,
                )
            fd, name = tempfile.mkstemp(prefix="geosyn-log-", suffix=".spool", dir=where)
            self._fd, self.path = fd, Path(name)
            os.ftruncate(fd, offset)  # sparse: blocks are taken as rows are written
        except SpoolError:
            raise
        except OSError as err:
            self.discard()
            raise SpoolError(
                err.errno, f"cannot create a spool file: {err.strerror}", where
            ) from err

    def flush(self, n: int) -> None:
        """Append rows ``0 .. n-1`` and their derived fields to the spool file; the
        buffers are refilled with their ``fill`` for the next chunk."""
        rows = self.rows
        head = {name: a[:n] for name, a in rows.items()}
        derived, self._effort_sum = derive_rows(head, self.control_dt, self._effort_sum)
        try:
            for name, block in (head | derived).items():
                if name in self._offsets:
                    self._write(block, self._offsets[name] + self.written * (block.nbytes // n))
        except OSError as err:
            where = str(self.path)
            self.discard()
            raise SpoolError(err.errno, f"cannot write the log: {err.strerror}", where) from err
        for f in _SPOOLED:
            if f.source == "tick":
                rows[f.name][:n] = f.fill
        self.written += n

    def _write(self, block: np.ndarray, offset: int) -> None:
        view = memoryview(np.ascontiguousarray(block).data).cast("B")
        while view:
            done = os.pwrite(self._fd, view, offset)
            view, offset = view[done:], offset + done

    def finish(self, done: int) -> dict[str, np.ndarray]:
        """The log of the ``done`` ticks that ran: ``{name: (done, ...) array}`` for every
        tick and derived field (read-only maps of the spool file when spooled)."""
        if not self.spooled or self.written == 0:  # short, or stopped within the first chunk
            rows = finish_rows(self.rows, done - self.written, self.control_dt)
            self.discard()
            return rows
        if done > self.written:
            self.flush(done - self.written)
        try:
            mm = mmap.mmap(self._fd, 0, access=mmap.ACCESS_READ)
        except OSError as err:
            where = str(self.path)
            self.discard()
            raise SpoolError(err.errno, f"cannot map the log: {err.strerror}", where) from err
        self.discard()  # the map keeps the data; the file's name goes now
        out: dict[str, np.ndarray] = {}
        for f in _SPOOLED:
            shape = (done, *(self._dims[d] for d in f.shape if d != "T"))
            if f.name in self._offsets:
                count = math.prod(shape)
                flat: np.ndarray = np.frombuffer(
                    mm, f.dtype, count=count, offset=self._offsets[f.name]
                )
                out[f.name] = flat.reshape(shape)
            else:  # no bytes per tick (no payloads): nothing to map
                out[f.name] = np.zeros(shape, dtype=f.dtype)
        return out

    def discard(self) -> None:
        """Close and remove the spool file and drop the buffers (idempotent); the arrays
        `finish` returned stay valid."""
        self.rows = {}
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1
        if self.path is not None:
            self.path.unlink(missing_ok=True)
            self.path = None


MAX_LOG_BYTES = 4 << 30
"""Largest per-tick log of one `geosyn.sim.Simulation.run` [bytes] (4 GiB): a longer run
is refused before anything is allocated (`open_log`). A run of more than ``SPOOL_CHUNK``
ticks holds one chunk in memory and the rest in its spool file, so this bounds disk."""


def open_log(
    n_ticks: int,
    dims: Mapping[str, int],
    control_dt: float,
    spool_dir: str | os.PathLike[str] | None = None,
) -> LogWriter:
    """The log of a run of ``n_ticks`` ticks of ``control_dt`` [s] with dimensions ``dims``
    (``nq``, ``nv``, ``P``), spooled when long; `InvalidArgument` over `MAX_LOG_BYTES`."""
    log_bytes = n_ticks * row_bytes(dims)
    if log_bytes > MAX_LOG_BYTES:  # e.g. duration 2e4 s: refuse, do not allocate
        raise InvalidArgument(
            f"duration={n_ticks * control_dt:g} s is {n_ticks} ticks of {control_dt:g} s whose"
            f" log needs {log_bytes / 2**30:.3g} GiB, more than MAX_LOG_BYTES ="
            f" {MAX_LOG_BYTES / 2**30:g} GiB; shorten the run or raise"
            " geosyn.sim.log_spool.MAX_LOG_BYTES"
        )
    return LogWriter(n_ticks, dims, control_dt, spool_dir)


__all__ = [
    "MAX_LOG_BYTES",
    "SPOOL_CHUNK",
    "LogWriter",
    "SpoolError",
    "open_log",
    "row_bytes",
    "spool_directory",
]
