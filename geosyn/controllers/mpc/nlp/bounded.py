"""`BoundedSolver`: an NLP solve bounded in wall time whatever its settings, and one that
a signal (SIGTERM, Ctrl-C) interrupts at once.

Two facts of the plugins shape it. fatrop has no time limit and no iteration callback,
and it iterates on through failed or NaN evaluations, so nothing inside a native call
can stop it before its ``max_iter``. And a native call holds the calling thread until it
returns, so Python's signal handlers (which run on the main thread only) wait for it.
Hence:

- fatrop is called for at most `FATROP_CHUNK` iterations at a time; a solve that needs
  more continues from the last iterate (the warm solver: barrier parameter ``mu_warm``)
  while the time budget lasts and the iterations stay within ``max_iter``. The budget is
  checked between calls, so a solve overruns it by at most one call of `FATROP_CHUNK`
  iterations. A solve stopped by its budget fails with a status that says so. With
  ``max_iter <= FATROP_CHUNK`` (the default 50) a solve is one call, as before.
- IPOPT stops itself at the budget (``max_wall_time``) and is called once.
- Each native call runs on a worker thread (CasADi releases the GIL while it solves)
  while the calling main thread waits, interruptibly: a signal handler runs as soon as
  the signal arrives and its exception (the CLI's ``SystemExit(143)`` on SIGTERM,
  ``KeyboardInterrupt``) propagates at once; the abandoned call finishes its chunk on the
  daemon worker, which the process's exit does not wait for. Off the main thread the call
  is made directly (no signal handler could run there anyway). Short calls too go to the
  worker: on the main thread CasADi itself runs pending signal handlers inside its calls
  and turns their exception into its own interrupt, which the solve swallows (a SIGTERM
  would be lost). The hand-over costs tens of microseconds per call (0-24 % of a 0.35 ms
  planar2 solve on a loaded machine,
  `benchmarks/hardening_solves.py`).
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import casadi as ca

__all__ = ["FATROP_CHUNK", "BoundedSolver", "call_interruptibly", "native_call_running"]

FATROP_CHUNK = 50
"""Most fatrop iterations in one native call (the default ``max_iter``)."""

_FATROP_MAX_ITER = 1  # fatrop's return_flag: stopped at its iteration limit


@dataclass(eq=False)
class _Job:
    fn: Callable[[], Any]
    done: threading.Event = field(default_factory=threading.Event)
    result: Any = None
    error: BaseException | None = None


class _Worker:
    """One daemon thread that runs jobs in order (started on first use)."""

    def __init__(self) -> None:
        self._jobs: queue.SimpleQueue[_Job] = queue.SimpleQueue()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self.last: _Job | None = None

    def submit(self, fn: Callable[[], Any]) -> _Job:
        job = _Job(fn)
        with self._lock:
            if self._thread is None or not self._thread.is_alive():
                self._thread = threading.Thread(
                    target=self._loop, name="geosyn-native-solve", daemon=True
                )
                self._thread.start()
        self._jobs.put(job)
        self.last = job
        return job

    def _loop(self) -> None:
        while True:
            job = self._jobs.get()
            try:
                job.result = job.fn()
            except BaseException as err:  # handed to the waiting caller
                job.error = err
            finally:
                job.done.set()


_WORKER = _Worker()


def native_call_running() -> bool:
    """True while the worker still runs a call (one abandoned by a signal, for instance)."""
    last = _WORKER.last
    return last is not None and not last.done.is_set()


def call_interruptibly(fn: Callable[[], Any]) -> Any:
    """``fn()`` on the worker thread, the main thread waiting interruptibly.

    Args:
        fn: a call that releases the GIL for its long part (a CasADi function).

    Returns:
        What ``fn`` returned.

    Raises:
        BaseException: what ``fn`` raised, or what a signal handler raised meanwhile
            (then ``fn`` finishes on the worker, unobserved).
    """
    if threading.current_thread() is not threading.main_thread():
        return fn()
    job = _WORKER.submit(fn)
    job.done.wait()  # a lock wait: signal handlers run (and may raise) while it waits
    if job.error is not None:
        raise job.error
    return job.result


class BoundedSolver:
    """A ``casadi.nlpsol`` function called within a wall-time budget (see the module).

    Called like the CasADi function (``solver(p=..., lbx=..., x0=...)``) and ``stats()``
    after it, with ``iter_count`` the total over its calls and, for a solve its budget
    stopped, ``success`` False and a ``return_status`` naming the budget.

    Args:
        first: the solver of the first call (warm or cold).
        then: the solver that continues from an iterate (warm), or None: one call only.
        max_iter: iteration limit of the whole solve.
        max_solve_time: wall-time budget of one solve [s].
    """

    def __init__(
        self,
        first: ca.Function,
        then: ca.Function | None,
        max_iter: int,
        max_solve_time: float,
    ) -> None:
        self.first = first
        self.then = then
        self.max_iter = max_iter
        self.max_solve_time = max_solve_time
        self._stats: dict[str, Any] = {}

    def stats(self) -> dict[str, Any]:
        """The statistics of the last solve (CasADi's, of its last call, with the totals)."""
        return self._stats

    def __call__(self, **kwargs: Any) -> dict[str, Any]:
        """One solve (allocates): ``casadi.nlpsol`` inputs in, its outputs out."""
        start = time.perf_counter()
        res, stats = _solve(self.first, kwargs)
        total = int(stats.get("iter_count", 0))
        calls = 1
        while self.then is not None and _at_iteration_limit(stats) and total < self.max_iter:
            if time.perf_counter() - start >= self.max_solve_time:
                stats = dict(stats, success=False)
                stats["return_status"] = (
                    f"max_solve_time {self.max_solve_time:.3g} s reached after {total} "
                    f"iterations in {calls} calls (max_iter {self.max_iter})"
                )
                break
            step = dict(kwargs, x0=res["x"], lam_x0=res["lam_x"], lam_g0=res["lam_g"])
            res, stats = _solve(self.then, step)
            total += int(stats.get("iter_count", 0))
            calls += 1
        self._stats = dict(stats, iter_count=total, solver_calls=calls)
        return res


def _solve(solver: ca.Function, kwargs: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """One native call and its statistics (read on the thread that made the call)."""
    return call_interruptibly(lambda: (solver(**kwargs), solver.stats()))


def _at_iteration_limit(stats: dict[str, Any]) -> bool:
    """fatrop stopped at its iteration limit (its chunk), not converged nor failed."""
    plugin = stats.get("fatrop")
    return isinstance(plugin, dict) and plugin.get("return_flag") == _FATROP_MAX_ITER
