"""Summaries of runs: ``summary.json`` (flat scalars) and ``summary.md`` (readable tables),
written by the runner and by ``geosyn report`` (`geosyn.experiments.results.report`)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.markup import escape  # units read [rad], which rich takes for a style
from rich.table import Table

from geosyn.experiments.run.run_metrics import unit_of


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


def unit_label(name: str, units: dict[str, str] | None) -> str:
    """``name [unit]`` (``units`` first, then the standard metrics' units), or ``name``."""
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
        lines.append("| | " + " | ".join(unit_label(c, units) for c in cols) + " |")
        lines.append("|---|" + "---|" * len(cols))
        for r in rows:
            lines.append(f"| {r} | " + " | ".join(fmt(cells.get((r, c), "")) for c in cols) + " |")
        lines.append("")
    if plain:
        lines += ["| quantity | value |", "|---|---|"]
        lines += [f"| {unit_label(k, units)} | {fmt(v)} |" for k, v in plain.items()]
        lines.append("")
    return "\n".join(lines)


def print_summary(
    title: str, summary: dict[str, float], units: dict[str, str] | None = None
) -> None:
    """Print the summary tables to the terminal (rich)."""
    plain, rows, cols, cells = split_summary(summary)
    console = Console(width=max(Console().width, 100))
    if rows:
        table = Table(title=title)
        # metrics as rows, runs (controllers, paths) as columns: fits a terminal
        table.add_column("")
        for r in rows:
            table.add_column(r, justify="right")
        for c in cols:
            table.add_row(escape(unit_label(c, units)), *(fmt(cells.get((r, c), "")) for r in rows))
        console.print(table)
    if plain:
        table = Table(title=title if not rows else None)
        table.add_column("quantity")
        table.add_column("value", justify="right")
        for k, v in plain.items():
            table.add_row(escape(unit_label(k, units)), fmt(v))
        console.print(table)


#: Row values that stay meaningful when a row's run did not complete: whether it did, its
#: wall time, and facts of the plan made before the run (path energies, planned
#: clearance). Every metric of the run itself, counts included (saturations, fallbacks,
#: contact force and time: counted up to the stop they would read as a clean run), was
#: measured on a truncated run and becomes NaN ("not measured"; the log has the run).
KEPT_WHEN_FAILED = frozenset(
    {
        "ok",
        "wall_time",
        "path_energy",
        "energy_shaped_metric",
        "energy_unshaped_metric",
        "planned_clearance",
        "planned_sphere_clearance",
        "planned_certified_clearance",
    }
)


#: Words that mark a plain summary key as a claim derived by comparing runs (not
#: established, NaN, when any run failed).
DERIVED_CLAIMS = ("ratio", "saving", "reduction", "speedup", "improvement")


def clean_summary(summary: dict[str, Any]) -> dict[str, float]:
    """Floats only (bools and ints converted); JSON-safe; failed runs marked.

    A run whose ``ok`` (``<row>.ok`` or plain ``ok``) is not 1 diverged, stopped or its
    controller failed: its metrics other than `KEPT_WHEN_FAILED` become NaN (never a 0.0
    that reads as perfect), plain derived claims (keys naming one of `DERIVED_CLAIMS`:
    ratios, savings, reductions; they compare runs) become NaN, ``claims_established`` is 0
    (1 when every run is ok), and ``failed_runs`` counts such runs (both present whenever
    the summary has ``ok`` keys).
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
            if "." not in key and any(word in key for word in DERIVED_CLAIMS):
                out[key] = math.nan
    out["claims_established"] = 0.0 if failed else 1.0
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


__all__ = [
    "DERIVED_CLAIMS",
    "KEPT_WHEN_FAILED",
    "clean_summary",
    "fmt",
    "markdown_summary",
    "print_summary",
    "split_summary",
    "unit_label",
    "write_summary",
]
