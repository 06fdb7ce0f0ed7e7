"""Where the runs of a sweep execute: this process, local worker processes, or Ray.

Local workers are forked (Linux) and die with the sweep: the kernel kills them when the
sweep process dies, even by ``kill -9`` (``PR_SET_PDEATHSIG``), so no orphan keeps running
(or keeps a run directory locked). A SIGTERM to the sweep stops its workers within
`WORKER_GRACE` seconds: they get SIGTERM (their runs remove their partial directories),
then SIGKILL. Ray: the address is checked (``local``, ``auto``, ``HOST:PORT``,
``ray://HOST:PORT``), a TCP connection is tried for `RAY_CONNECT_TIMEOUT` seconds before
``ray.init``, and token authentication (Ray >= 2.60) is explained in one line.
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import os
import re
import signal
import socket
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from geosyn.core.errors import GeosynError
from geosyn.experiments.errors import ConfigError, ProcedureFailed
from geosyn.experiments.run import termination

#: A function running one sweep job: ``job -> (run directory, summary)``.
JobFunction = Callable[[Any], tuple[str, dict[str, float]]]
#: Seconds to wait for a Ray head to accept a connection.
RAY_CONNECT_TIMEOUT = 10.0
#: Seconds a stopped sweep gives its workers to clean up after SIGTERM, before SIGKILL.
WORKER_GRACE = 2.0


def _worker_init(parent: int) -> None:
    """In each worker process: die with the sweep (no orphans, even after ``kill -9``).

    Linux: the kernel kills the worker when its parent dies (``PR_SET_PDEATHSIG`` with
    SIGKILL: immediate, even inside a long solver call; the partial run directory it
    leaves is removed by the next run of the sweep, and its lock dies with it).
    Elsewhere a daemon thread polls the parent's pid. A SIGTERM from the sweep ends the
    worker's run through `termination` (its partial directory removed), then the worker.
    """
    termination.install()
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGKILL, 0, 0, 0)  # PR_SET_PDEATHSIG = 1
        if os.getppid() != parent:  # the parent died before prctl took effect
            os._exit(137)
        return

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(137)

    threading.Thread(target=watch, daemon=True).start()


def _worker_job(job_fn: JobFunction, job: Any) -> tuple[str, dict[str, float]]:
    """`run_job` in a worker process; a SIGTERM (``SystemExit``) ends the process after
    the run cleaned up, instead of returning to the pool's loop."""
    try:
        return job_fn(job)
    except SystemExit as exc:
        os._exit(exc.code if isinstance(exc.code, int) else 143)


@contextlib.contextmanager
def _terminating(pool: ProcessPoolExecutor) -> Iterator[None]:
    """Shut ``pool`` down; on an error or a signal, stop its running workers at once.

    A normal exit waits for the workers; otherwise they get SIGTERM (their runs remove
    their partial directories) and, after `WORKER_GRACE` seconds, SIGKILL.
    """
    try:
        yield
    except BaseException:
        procs = list(getattr(pool, "_processes", {}).values())
        for proc in procs:
            with contextlib.suppress(Exception):
                proc.terminate()
        deadline = time.monotonic() + WORKER_GRACE
        for proc in procs:
            proc.join(max(0.0, deadline - time.monotonic()))
            if proc.is_alive():
                proc.kill()
                proc.join(WORKER_GRACE)  # dead (its lock released) before the sweep goes on
        # no cancel_futures: the pool's manager thread fails the pending futures itself
        # (cancelling them as well races with it: InvalidStateError, Python 3.11)
        pool.shutdown(wait=False)
        raise
    pool.shutdown(wait=True)


def run_local(
    jobs: Sequence[Any], workers: int, advance: Callable[[], None], job_fn: JobFunction
) -> None:
    """Run ``job_fn(job)`` for each job: in this process (``workers == 1``) or on a pool of
    worker processes that die with this one; a geosyn error of a run stops the sweep."""
    if workers == 1:
        for job in jobs:
            termination.raise_if_terminated()
            job_fn(job)
            advance()
        return
    # Linux: fork, so workers inherit the already imported pinocchio/casadi/mujoco (a
    # forkserver re-imports them in every sweep; the speed-ups are in benchmarks/RESULTS.md).
    # Workers only run experiments and never use the parent's progress thread. Elsewhere:
    # a forkserver that preloads geosyn.
    if sys.platform.startswith("linux"):
        ctx = multiprocessing.get_context("fork")
    else:
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(["geosyn.experiments.sweep", "geosyn.experiments.procedures"])
    pool = ProcessPoolExecutor(
        max_workers=workers, mp_context=ctx, initializer=_worker_init, initargs=(os.getpid(),)
    )
    with _terminating(pool):
        pending = {pool.submit(_worker_job, job_fn, job): job for job in jobs}
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            termination.raise_if_terminated()
            for fut in done:
                job = pending.pop(fut)
                try:
                    fut.result()
                except GeosynError as err:
                    raise ProcedureFailed(
                        f"run {job.out!r} failed: {type(err).__name__}: {err}"
                    ) from err
                except BrokenProcessPool as err:
                    raise ProcedureFailed(
                        f"a worker process died during run {job.out!r} (killed by a signal or"
                        " out of memory?); re-run the sweep to complete the missing runs"
                    ) from err
                advance()


_RAY_ADDRESS = re.compile(r"^(?:ray://)?(\[[0-9A-Fa-f:]+\]|[A-Za-z0-9][A-Za-z0-9.\-]*):(\d{1,5})$")


def check_ray_address(address: object) -> str:
    """``"local"``, ``"auto"``, ``HOST:PORT`` or ``ray://HOST:PORT``, else a `ConfigError`."""
    text = str(address).strip()
    if text in ("local", "auto"):
        return text
    m = _RAY_ADDRESS.match(text)
    if m is None or not 0 < int(m.group(2)) < 65536:
        raise ConfigError(
            "--ray",
            text,
            "expected 'local', 'auto', HOST:PORT or ray://HOST:PORT with a port in"
            " 1-65535 (e.g. 127.0.0.1:6379)",
        )
    return text


#: HTTP/2 client preface and an empty SETTINGS frame: a gRPC server (a Ray head's GCS, a
#: Ray Client server) answers with a SETTINGS frame.
_HTTP2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + b"\x00\x00\x00\x04\x00\x00\x00\x00\x00"
_HTTP2_SETTINGS = 0x4


def _check_reachable(address: str, timeout: float) -> None:
    """Raise a `ConfigError` unless a gRPC (HTTP/2) server answers at ``address`` within
    ``timeout`` [s]: ``ray.init`` retries an address without a Ray head for minutes.
    """
    if address in ("local", "auto"):
        return
    m = _RAY_ADDRESS.match(address)
    if m is None:  # pragma: no cover - check_ray_address ran first
        return
    host, port = m.group(1).strip("[]"), int(m.group(2))
    try:
        with socket.create_connection((host, port), timeout=timeout) as sock:
            sock.settimeout(timeout)
            sock.sendall(_HTTP2_PREFACE)
            header = b""
            while len(header) < 9:
                chunk = sock.recv(9 - len(header))
                if not chunk:
                    break
                header += chunk
    except TimeoutError:
        header = b""
    except OSError as err:
        raise ConfigError(
            "--ray",
            address,
            f"cannot connect within {timeout:g} s ({err.strerror or err}); is a Ray head"
            " running there (ray start --head --port PORT)?",
        ) from None
    if len(header) < 9 or header[3] != _HTTP2_SETTINGS:
        raise ConfigError(
            "--ray",
            address,
            f"something listens there but does not answer like a Ray head (no gRPC reply"
            f" within {timeout:g} s); check the port the head printed (ray start --head)",
        )


#: Ray's switch for multi-node clusters: on Linux it is on by default, and then a local
#: cluster's GCS, raylet and workers listen on every interface with the machine's address
#: (Ray maps 127.0.0.1 to it); off, they listen on 127.0.0.1 only (checked with ``ss -ltn``).
_RAY_CLUSTER_ENV = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"


def _loopback_only_local_cluster() -> None:
    """Make a ``--ray local`` cluster listen on 127.0.0.1 only (said once if overridden).

    Ray reads the switch when it is imported and its processes inherit it, so it is set
    before the import (and applied to a Ray imported earlier in this process). An
    exported value is kept: off ("0", "false") it is applied the same way, on it is
    reported.
    """
    value = os.environ.get(_RAY_CLUSTER_ENV)
    if value is None or value.strip().lower() in ("0", "false"):
        os.environ.setdefault(_RAY_CLUSTER_ENV, "0")
        # Ray imported earlier in this process read the switch then: set what it read
        constants = sys.modules.get("ray._private.ray_constants")
        if constants is not None:
            setattr(constants, "ENABLE_RAY_CLUSTER", False)  # noqa: B010
    else:
        warnings.warn(
            f"--ray local: {_RAY_CLUSTER_ENV}={value} is set, so the local Ray cluster"
            " listens on every network interface, not only 127.0.0.1",
            RuntimeWarning,
            stacklevel=3,
        )


def _ray_init(ray: Any, address: str, workers: int) -> None:
    """``ray.init`` with a connection check first and one-line errors."""
    _check_reachable(address, RAY_CONNECT_TIMEOUT)
    try:
        if address == "local":
            ray.init(num_cpus=max(workers, 1), include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, include_dashboard=False, log_to_driver=False)
    except Exception as err:
        text = " ".join(str(err).split())
        if type(err).__name__ == "AuthenticationError" or "token" in text.lower():
            raise ConfigError(
                "--ray",
                address,
                "the cluster requires token authentication (Ray >= 2.60 enables it by"
                " default): export RAY_AUTH_MODE=token and RAY_AUTH_TOKEN=<the head's token>"
                " (or RAY_AUTH_TOKEN_PATH), then retry",
            ) from None
        hint = ""
        if os.environ.get("RAY_AUTH_MODE", "").lower() != "token":
            # Ray 2.60 heads use token authentication by default, and a client without
            # RAY_AUTH_MODE=token only sees a ConnectionError (measured: after ~20 s).
            hint = (
                "; if the head uses token authentication (the default since Ray 2.60),"
                " export RAY_AUTH_MODE=token (token from ~/.ray/auth_token or RAY_AUTH_TOKEN)"
                " and retry"
            )
        raise ConfigError(
            "--ray",
            address,
            f"could not connect to Ray: {type(err).__name__}: {text[:300]}{hint}",
        ) from None


def run_ray(
    jobs: Sequence[Any],
    address: str,
    workers: int,
    advance: Callable[[], None],
    job_fn: JobFunction,
) -> None:
    """Run ``job_fn(job)`` for each job as Ray tasks (one CPU each); see `_ray_init`."""
    if address == "local":
        _loopback_only_local_cluster()
    try:  # deferred: ray is the optional 'distributed' extra
        import ray
    except ImportError as err:
        raise ConfigError(
            "--ray", address, "needs the 'distributed' extra: pip install 'geosyn[distributed]'"
        ) from err
    started = False
    if not ray.is_initialized():
        before = _sigterm_handler()
        _ray_init(ray, address, workers)
        started = True
        _reclaim_sigterm(before)
    pending: list[Any] = []
    try:
        remote = ray.remote(num_cpus=1)(job_fn)
        refs = {remote.remote(job): job for job in jobs}
        pending = list(refs)
        while pending:
            try:  # a timeout, so that a SIGTERM is handled within a second
                done, pending = ray.wait(pending, num_returns=1, timeout=1.0)
            except SystemExit:  # Ray turns a signal inside wait into SystemExit(1)
                termination.raise_if_terminated()
                raise
            termination.raise_if_terminated()
            for ref in done:
                try:
                    ray.get(ref)
                except Exception as err:
                    raise ProcedureFailed(
                        f"run {refs[ref].out!r} failed on Ray: {err}".splitlines()[0]
                    ) from err
                advance()
    except BaseException:
        if not started:  # the caller's Ray session goes on: stop this sweep's tasks
            _cancel_running(ray, pending)
        # else ray.shutdown() below ends the job, and the cluster kills its workers (their
        # partial runs are removed on re-run). No ray.cancel then: cancelling a task whose
        # result is just arriving aborts the driver in Ray 2.60 (a failed RAY_CHECK
        # "Tried to complete task that was not pending", a stack dump and exit 1).
        raise
    finally:
        if started:
            ray.shutdown()


def _cancel_running(ray: Any, refs: list[Any]) -> None:
    """Force-cancel the tasks of ``refs`` that have not finished (their processes end)."""
    if not refs:
        return
    with contextlib.suppress(Exception):
        _, refs = ray.wait(refs, num_returns=len(refs), timeout=0)
    for ref in refs:
        with contextlib.suppress(Exception):
            ray.cancel(ref, force=True)


def _sigterm_handler() -> Any:
    """The Python SIGTERM handler (None off the main thread)."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.getsignal(signal.SIGTERM)


def _reclaim_sigterm(before: Any) -> None:
    """Re-install the SIGTERM handler that was active before ``ray.init``.

    ``ray.init`` installs its own (``sys.exit(15)`` in Python, a stack dump from its C++
    core), which would bypass `termination` (exit 143, runs stopped and cleaned up). Only
    a Python handler (e.g. the CLI's) is put back; main thread only.
    """
    if callable(before) and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, before)


__all__ = [
    "RAY_CONNECT_TIMEOUT",
    "WORKER_GRACE",
    "JobFunction",
    "check_ray_address",
    "run_local",
    "run_ray",
]
