"""Summaries of runs: ``summary.json`` (flat scalars) and ``summary.md`` (readable tables),
and ``geosyn report RUN_DIR`` (regenerate both and the plots from results.npz + config).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from geosyn.experiments.errors import ExperimentError


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
    u = (units or {}).get(name)
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
            table.add_row(_unit(c, units), *(fmt(cells.get((r, c), "")) for r in rows))
        console.print(table)
    if plain:
        table = Table(title=title if not rows else None)
        table.add_column("quantity")
        table.add_column("value", justify="right")
        for k, v in plain.items():
            table.add_row(_unit(k, units), fmt(v))
        console.print(table)


def clean_summary(summary: dict[str, Any]) -> dict[str, float]:
    """Floats only (bools and ints converted); JSON-safe."""
    out: dict[str, float] = {}
    for k, v in summary.items():
        out[str(k)] = float(v)
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


def load_results(run_dir: Path) -> dict[str, np.ndarray]:
    """The arrays of ``run_dir/results.npz``."""
    path = Path(run_dir) / "results.npz"
    if not path.is_file():
        raise ExperimentError(
            f"run_dir {str(run_dir)!r} has no results.npz; is it a run directory?"
        )
    with np.load(path, allow_pickle=False) as data:
        return {k: np.array(data[k]) for k in data.files}


def report(run_dir: str | Path, quiet: bool = False) -> dict[str, float]:
    """Regenerate summary.json, summary.md and the plots of a run directory.

    Raises:
        ExperimentError: not a run directory.
        ConfigError: its config.yaml no longer validates.
    """
    from geosyn.experiments.loader import load_config
    from geosyn.experiments.procedures import PROCEDURES

    run_dir = Path(run_dir)
    if not (run_dir / "config.yaml").is_file():
        raise ExperimentError(
            f"run_dir {str(run_dir)!r} has no config.yaml; is it a run directory?"
        )
    results = load_results(run_dir)
    cfg, _ = load_config(run_dir / "config.yaml")
    proc = PROCEDURES[cfg.kind]()
    params = proc.Params.model_validate(cfg.params)
    summary = clean_summary(proc.summarize(cfg, params, results))
    if cfg.outputs.plots:
        proc.plot(cfg, params, results, run_dir)
    write_summary(run_dir, cfg.name, cfg.description, summary, proc.units)
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
