"""One process compiles a library at a time: a cold cache shared by concurrent processes
(a sweep's workers) compiles each library once (`geosyn.core.cache_folder.cache_lock`)."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import casadi as ca
import pytest

from geosyn.core import cache_folder, codegen

# The start of every race script: ``folder``, ``runs`` and the names of the two processes
# from argv; ``slowed(f)``, f that first logs its call to ``runs`` and sleeps 1 s (so that
# without a lock both processes find the cache empty and both do the work); ``barrier()``,
# the point both processes reach before racing.
RACE_PRELUDE = """
import os, sys, time
from pathlib import Path

folder, runs, me, other = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3], sys.argv[4]


def slowed(real):
    def slow(*args):
        with open(runs, "a") as fh:
            fh.write(f"{os.getpid()}\\n")
        time.sleep(1.0)
        return real(*args)
    return slow


def barrier():
    (folder / f"ready-{me}").touch()
    deadline = time.monotonic() + 60
    while not (folder / f"ready-{other}").exists():
        assert time.monotonic() < deadline, "the other process never came"
        time.sleep(0.005)
"""

# Both processes compile the same new function into the cache ``folder``.
_WORKER = """
import casadi as ca
from geosyn.core import codegen, library_cache

library_cache.run_compiler = slowed(library_cache.run_compiler)
x = ca.SX.sym("x", 3)
fun = ca.Function("lock_probe", [x], [ca.sin(x) * ca.dot(x, x)], ["x"], ["y"])
barrier()
out = codegen.compile_function(fun, folder)
print(repr(float(out([0.1, -0.2, 0.3])[2])))
"""


def race_pair(script: str, folder: Path, runs: Path) -> list[str]:
    """Run `RACE_PRELUDE` + ``script`` as two processes at once, racing in ``folder`` and
    logging the slowed calls to ``runs``; their stripped stdouts after both exit 0."""
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", RACE_PRELUDE + script, str(folder), str(runs), me, other],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for me, other in (("a", "b"), ("b", "a"))
    ]
    outs = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [err[-2000:] for _, err in outs]
    return [out.strip() for out, _ in outs]


def test_concurrent_processes_on_a_cold_cache_compile_once(tmp_path: Path) -> None:
    """Two processes asking for the same library at once: one compiler run, both get the
    uncompiled function's numbers (to 1e-15), one library, no lock file left; clear_cache
    takes a lock file a killed process left."""
    cache, runs = tmp_path / "cache", tmp_path / "runs.txt"
    cache.mkdir()
    outs = race_pair(_WORKER, cache, runs)
    x = ca.SX.sym("x", 3)
    fun = ca.Function("lock_probe", [x], [ca.sin(x) * ca.dot(x, x)])
    expected = float(fun([0.1, -0.2, 0.3])[2])
    for out in outs:
        assert abs(float(out) - expected) <= 1e-15 * abs(expected)
    assert len(runs.read_text().split()) == 1  # one compiler run for both processes
    (library,) = cache.glob("lock_probe_*.so")
    assert not list(cache.glob("*.lock"))  # the lock went with the compile
    left = library.with_suffix(".lock")  # as a process killed while compiling leaves it
    left.touch()
    codegen.clear_cache(cache)
    assert not list(cache.glob("lock_probe_*"))


def test_a_lock_held_too_long_is_waited_for_then_reported(tmp_path: Path) -> None:
    """Another holder past the wait bound: a RuntimeWarning, and the block still runs
    (after at least the bound); a lock released within the bound is taken silently."""
    path = tmp_path / "probe.lock"
    held, release = threading.Event(), threading.Event()

    def holder() -> None:
        with cache_folder.cache_lock(path):
            held.set()
            release.wait(30)

    thread = threading.Thread(target=holder)
    thread.start()
    try:
        assert held.wait(30)
        start = time.monotonic()
        with (
            pytest.warns(RuntimeWarning, match=path.name),
            cache_folder.cache_lock(path, wait=0.3),
        ):
            waited = time.monotonic() - start
        assert waited >= 0.3
    finally:
        release.set()
        thread.join(30)
    timer = threading.Timer(0.2, release.set)
    held.clear()
    release.clear()
    thread = threading.Thread(target=holder)
    thread.start()
    assert held.wait(30)
    timer.start()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with cache_folder.cache_lock(path, wait=60.0):
            pass
    thread.join(30)


def test_a_file_system_without_locks_runs_unlocked_and_says_so_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """flock failing with ENOLCK (some network file systems): the block runs, with one
    RuntimeWarning per process; the compile still gives the uncompiled numbers."""
    import errno
    import fcntl

    def no_locks(fd: int, op: int) -> None:
        raise OSError(errno.ENOLCK, "No locks available")

    monkeypatch.setattr(fcntl, "flock", no_locks)
    monkeypatch.setattr(cache_folder, "_unlocked_warned", False)
    ran = []
    with pytest.warns(RuntimeWarning, match="cannot lock"):
        with cache_folder.cache_lock(tmp_path / "a.lock"):
            ran.append(1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        x = ca.SX.sym("x", 2)
        fun = ca.Function("unlocked_probe", [x], [ca.exp(x[0]) * x[1]])
        out = codegen.compile_function(fun, tmp_path / "cache")
    assert ran == [1]
    assert abs(float(out([0.3, 2.0])) - float(fun([0.3, 2.0]))) <= 1e-15 * 2.7


def test_store_json_replaces_an_entry_whole_and_warns_when_it_cannot(tmp_path: Path) -> None:
    """`store_json` writes a record that `json` reads back equal, replacing the old entry
    and leaving no temporary file in the folder; where the folder cannot be made (a file
    stands in its place) it warns, names the cache, and raises nothing."""
    import json

    path = tmp_path / "entries" / "thing_0123.json"
    cache_folder.store_json(path, {"a": [1.5, 2.0]}, "the test cache")
    cache_folder.store_json(path, {"a": [3.25], "b": "x"}, "the test cache")
    assert json.loads(path.read_text()) == {"a": [3.25], "b": "x"}
    assert [p.name for p in path.parent.iterdir()] == [path.name]
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    with pytest.warns(RuntimeWarning, match="the test cache"):
        cache_folder.store_json(blocked / "x.json", [1], "the test cache")
    assert blocked.read_text() == "not a folder"
