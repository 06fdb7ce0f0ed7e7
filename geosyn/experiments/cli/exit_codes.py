"""The exit codes of the ``geosyn`` command line, in one table that ``--help`` prints."""

from __future__ import annotations

#: Success: the command did what it was asked (a run with at least one completed
#: closed-loop run, or without closed-loop runs).
OK = 0
#: An unexpected error (a bug: the traceback is printed).
INTERNAL_ERROR = 1
#: Bad input: a config, argument, robot file or run directory refused (one line on stderr).
BAD_INPUT = 2
#: The run was written, but none of its closed-loop runs completed (every controller
#: failed or diverged; their metrics are NaN, the causes on stderr and in ``run.log``).
NO_RUN_SUCCEEDED = 3
#: Stopped by SIGTERM (128 + 15), partial outputs removed.
TERMINATED = 143

#: code -> meaning, as ``geosyn --help`` and docs/experiments.md list them.
EXIT_CODES: dict[int, str] = {
    OK: "success",
    INTERNAL_ERROR: "internal error (a bug; please report the traceback)",
    BAD_INPUT: "bad input: config, arguments, robot file or output refused (one stderr line)",
    NO_RUN_SUCCEEDED: "geosyn run: no closed-loop run completed (all failed or diverged)",
    TERMINATED: "stopped by SIGTERM (partial outputs removed)",
}


def epilog() -> str:
    """The exit-code table as the text after ``--help``."""
    rows = "\n".join(f"  {code:<4} {meaning}" for code, meaning in EXIT_CODES.items())
    return f"exit codes:\n{rows}"


def run_exit_code(summary: dict[str, float]) -> int:
    """`NO_RUN_SUCCEEDED` when the summary has closed-loop runs (``ok`` keys) and none of
    them completed, else `OK`."""
    oks = [v for k, v in summary.items() if k.rpartition(".")[2] == "ok"]
    return NO_RUN_SUCCEEDED if oks and not any(v == 1.0 for v in oks) else OK


__all__ = [
    "BAD_INPUT",
    "EXIT_CODES",
    "INTERNAL_ERROR",
    "NO_RUN_SUCCEEDED",
    "OK",
    "TERMINATED",
    "epilog",
    "run_exit_code",
]
