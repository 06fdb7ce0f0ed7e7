"""Summaries of runs: ``summary.json`` (flat scalars) and ``summary.md`` (readable tables),
and ``geosyn report RUN_DIR`` (regenerate both and the plots from results.npz + config).
"""

from __future__ import annotations

import hashlib
import json
import math
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from geosyn.experiments.errors import ConfigError, ExperimentError


def fmt(x: Any) -> str:
    """A number for a table: 4 significant digits, ``nan``/``inf`` spelled out."""
    if isinstance(x, (bool, np.bool_)):
        return str(bool(x))
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    try:
        f = float(x)
    except (TypeError, ValueError):
        return str(x)
    if math.isnan(f) or math.isinf(f):
        return str(f)
    if f != 0 and (abs(f) < 1e-3 or abs(f) >= 1e5):
        return f"{f:.3e}"
    return f"{f:.4g}"


def split_summary(
    summary: dict[str, float],
) -> tuple[dict[str, float], list[str], list[str], dict[tuple[str, str], float]]:
    """(plain scalars, row names, column names, table cells) of a flat summary.

    Keys ``row.metric`` become table cells; keys without a dot stay plain scalars.
    """
    plain: dict[str, float] = {}
    rows: list[str] = []
    cols: list[str] = []
    cells: dict[tuple[str, str], float] = {}
    for key, value in summary.items():
        if "." in key:
            r, c = key.rsplit(".", 1)
            rows += [r] if r not in rows else []
            cols += [c] if c not in cols else []
            cells[(r, c)] = value
        else:
            plain[key] = value
    return plain, rows, cols, cells


def _unit(name: str, units: dict[str, str] | None) -> str:
    from geosyn.experiments.metrics import unit_of

    u = (units or {}).get(name) or unit_of(name)
    return f"{name} [{u}]" if u else name


def markdown_summary(
    title: str,
    description: str,
    summary: dict[str, float],
    status: str = "",
    units: dict[str, str] | None = None,
) -> str:
    """summary.md text: the description, the table, then the plain scalars.

    ``units`` maps a metric name (the part after the last dot) to its unit.
    """
    plain, rows, cols, cells = split_summary(summary)
    lines = [f"# {title}", ""]
    if description:
        lines += [description.strip(), ""]
    if status:
        lines += [status, ""]
    if rows:
        lines.append("| | " + " | ".join(_unit(c, units) for c in cols) + " |")
        lines.append("|---|" + "---|" * len(cols))
        for r in rows:
            lines.append(f"| {r} | " + " | ".join(fmt(cells.get((r, c), "")) for c in cols) + " |")
        lines.append("")
    if plain:
        lines += ["| quantity | value |", "|---|---|"]
        lines += [f"| {_unit(k, units)} | {fmt(v)} |" for k, v in plain.items()]
        lines.append("")
    return "\n".join(lines)


def print_summary(
    title: str, summary: dict[str, float], units: dict[str, str] | None = None
) -> None:
    """Print the summary tables to the terminal (rich)."""
    from rich.console import Console
    from rich.markup import escape  # units read [rad], which rich takes for a style
    from rich.table import Table

    plain, rows, cols, cells = split_summary(summary)
    console = Console(width=max(Console().width, 100))
    if rows:
        table = Table(title=title)
        # metrics as rows, runs (controllers, paths) as columns: fits a terminal
        table.add_column("")
        for r in rows:
            table.add_column(r, justify="right")
        for c in cols:
            table.add_row(escape(_unit(c, units)), *(fmt(cells.get((r, c), "")) for r in rows))
        console.print(table)
    if plain:
        table = Table(title=title if not rows else None)
        table.add_column("quantity")
        table.add_column("value", justify="right")
        for k, v in plain.items():
            table.add_row(escape(_unit(k, units)), fmt(v))
        console.print(table)


#: Row metrics that stay meaningful when a row's run did not complete: facts of the plan
#: (path energies, planned clearance) and counts up to the stop (an obstacle contact
#: before the stop happened, whatever came after); every other metric of a failed row was
#: measured on a truncated run and becomes NaN ("not measured").
KEPT_WHEN_FAILED = frozenset(
    {
        "ok",
        "wall_time",
        "fallbacks",
        "saturations",
        "max_contact_force",
        "contact_time",
        "path_energy",
        "energy_shaped_metric",
        "energy_unshaped_metric",
        "planned_clearance",
    }
)


def clean_summary(summary: dict[str, Any]) -> dict[str, float]:
    """Floats only (bools and ints converted); JSON-safe; failed runs marked.

    A run whose ``ok`` (``<row>.ok`` or plain ``ok``) is not 1 diverged, stopped or its
    controller failed: its metrics other than `KEPT_WHEN_FAILED` become NaN (never a 0.0
    that reads as perfect), plain ratios become NaN (they compare runs), and
    ``failed_runs`` counts such runs (present whenever the summary has ``ok`` keys).
    """
    out: dict[str, float] = {}
    for k, v in summary.items():
        out[str(k)] = float(v)
    oks = {k.rpartition(".")[0]: v for k, v in out.items() if k.rpartition(".")[2] == "ok"}
    if not oks:
        return out
    failed = [row for row, v in oks.items() if v != 1.0]
    for key in out:
        row, _, name = key.rpartition(".")
        if row in failed and name not in KEPT_WHEN_FAILED and (row or "ok" in out):
            out[key] = math.nan
    if failed:
        for key in out:
            if "." not in key and "ratio" in key:
                out[key] = math.nan
    out["failed_runs"] = float(len(failed))
    return out


def write_summary(
    out_dir: Path,
    title: str,
    description: str,
    summary: dict[str, float],
    units: dict[str, str] | None = None,
) -> None:
    """Write summary.md then summary.json (written last: it marks a complete run)."""
    (out_dir / "summary.md").write_text(markdown_summary(title, description, summary, units=units))
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=1, allow_nan=True) + "\n")


#: Largest results.npz `load_results` reads [bytes] (uncompressed size of its arrays).
MAX_RESULTS_BYTES = 4 << 30


def _rerun_hint(run_dir: Path) -> str:
    return (
        f"re-run it: geosyn run {str(run_dir / 'config.yaml')!r} --out NEW_DIR"
        " (the arrays cannot be rebuilt from the summaries)"
    )


def load_results(run_dir: Path) -> dict[str, np.ndarray]:
    """The arrays of ``run_dir/results.npz``, checked before use.

    The file must be an intact zip (every member's CRC is verified) of ``.npy`` arrays of
    plain numbers, booleans or text: no pickled objects (``allow_pickle=False``).

    Raises:
        ExperimentError: no results.npz, or a damaged one (truncated, bit-flipped, empty,
            pickled objects, too large); the message names the file and how to regenerate
            it.
    """
    run_dir = Path(run_dir)
    path = run_dir / "results.npz"
    if not path.is_file():
        raise ExperimentError(
            f"run_dir {str(run_dir)!r} has no results.npz; is it a run directory?"
        )

    def broken(reason: str) -> ExperimentError:
        return ExperimentError(f"{path} is damaged ({reason}); {_rerun_hint(run_dir)}")

    try:
        with zipfile.ZipFile(path) as archive:
            members = archive.infolist()
            total = sum(m.file_size for m in members)
            if total > MAX_RESULTS_BYTES:
                raise broken(f"its arrays take {total} bytes, more than {MAX_RESULTS_BYTES}")
            bad = archive.testzip()
            if bad is not None:
                raise broken(f"member {bad!r} fails its CRC check")
            if not members:
                raise broken("an empty archive")
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: np.array(data[k]) for k in data.files}
    except ExperimentError:
        raise
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError, KeyError) as err:
        reason = " ".join(str(err).split()) or type(err).__name__
        if "allow_pickle" in reason:
            reason = "it holds pickled Python objects, which are never loaded"
        raise broken(reason) from None
    for key, arr in arrays.items():
        if arr.dtype.kind not in "biufcUSM?":
            raise broken(f"array {key!r} has dtype {arr.dtype}, not numbers or text")
    problem = _shape_problem(arrays) or _digest_problem(run_dir, path)
    if problem:
        raise broken(problem)
    return arrays


def _shape_problem(arrays: dict[str, np.ndarray]) -> str | None:
    """Arrays of one logged run (``<run>__t``, ``<run>__q``, ...) disagree in length."""
    for key, t in arrays.items():
        if not key.endswith("__t") or t.ndim != 1:
            continue
        prefix = key[: -len("t")]
        for other, arr in arrays.items():
            if other.startswith(prefix) and arr.ndim >= 1 and arr.shape[0] != t.shape[0]:
                return f"array {other!r} has {arr.shape[0]} rows, {key!r} has {t.shape[0]}"
    return None


def _digest_problem(run_dir: Path, path: Path) -> str | None:
    """results.npz differs from the sha256 its run recorded in run.json (if it did)."""
    try:
        meta = json.loads((run_dir / "run.json").read_text())
    except (OSError, ValueError):
        return None  # no run.json (or an older run): nothing to compare with
    expected = meta.get("results_sha256") if isinstance(meta, dict) else None
    if not isinstance(expected, str):
        return None
    if hashlib.sha256(path.read_bytes()).hexdigest() != expected:
        return "its sha256 differs from the one run.json recorded: altered after the run"
    return None


def report(run_dir: str | Path, quiet: bool = False) -> dict[str, float]:
    """Regenerate summary.json, summary.md and the plots of a run directory (of a sweep
    directory: its tables and one plot per grid axis, `geosyn.experiments.report_sweep`;
    then the returned summary is empty).

    Raises:
        ExperimentError: not a run directory, a damaged results.npz, or results that do
            not match the config (each message names the file and how to regenerate it).
        ConfigError: its config.yaml is unreadable or no longer validates.
        OutputNotWritable: the summaries cannot be written.
    """
    from geosyn.experiments.loader import load_config
    from geosyn.experiments.procedures import PROCEDURES

    run_dir = Path(run_dir)
    if (run_dir / "sweep.yaml").is_file():  # a sweep directory: its tables and axis plots
        from geosyn.experiments.report_sweep import report_sweep

        report_sweep(run_dir, quiet=quiet)
        return {}
    if not (run_dir / "config.yaml").is_file():
        raise ExperimentError(
            f"run_dir {str(run_dir)!r} has no config.yaml; is it a run directory?"
        )
    results = load_results(run_dir)
    try:
        cfg, _ = load_config(run_dir / "config.yaml")
    except ConfigError as err:
        raise ConfigError(
            str(run_dir / "config.yaml"),
            err.field,
            f"{err.reason} (the run's saved config is damaged or from another version;"
            " re-run the experiment from its original config)",
        ) from None
    proc = PROCEDURES[cfg.kind]()
    params = proc.Params.model_validate(cfg.params)
    try:
        summary = clean_summary(proc.full_summary(cfg, params, results))
        if cfg.outputs.plots:
            proc.plot(cfg, params, results, run_dir)
    except OSError as err:  # a plot could not be written (read-only, disk full)
        from geosyn.experiments.errors import OutputNotWritable

        raise OutputNotWritable(run_dir, err) from err
    except (KeyError, IndexError, ValueError, TypeError) as err:
        # results.npz of another experiment, or arrays of the wrong shape
        reason = " ".join(str(err).split())
        raise ExperimentError(
            f"{run_dir / 'results.npz'} does not match {run_dir / 'config.yaml'}"
            f" (kind {cfg.kind!r}: {type(err).__name__}: {reason[:200]}); it was written"
            f" by another experiment or altered; {_rerun_hint(run_dir)}"
        ) from None
    try:
        write_summary(run_dir, cfg.name, cfg.description, summary, proc.units)
    except OSError as err:
        from geosyn.experiments.errors import OutputNotWritable

        raise OutputNotWritable(run_dir, err) from err
    if not quiet:
        print_summary(cfg.name, summary, proc.units)
    return summary


__all__ = [
    "clean_summary",
    "fmt",
    "load_results",
    "markdown_summary",
    "print_summary",
    "report",
    "split_summary",
    "write_summary",
]
