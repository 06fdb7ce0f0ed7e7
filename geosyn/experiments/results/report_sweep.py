"""``geosyn report SWEEP_DIR``: the tables of a sweep directory and one plot per grid axis.

A sweep directory (`geosyn.experiments.sweep`) holds ``sweep.yaml`` (source, grid,
seeds) and one run directory per grid point and seed. `report_sweep` re-reads every
complete run's ``summary.json``, rewrites ``sweep_summary.json``/``.md`` (mean ± std
over seeds, with units), prints the table, and draws ``sweep_<axis>.png`` for each grid
axis: the standard metrics of `geosyn.experiments.run.run_metrics` present in the summaries
(mean ± std over seeds) against the axis values, one line per summary row (controller)
and per combination of the other axes' values.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path
from typing import Any

import yaml
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from geosyn.experiments.errors import ExperimentError
from geosyn.experiments.results.aggregate import aggregate, point_name, write_aggregate
from geosyn.experiments.results.plots import COLORS, figure, save
from geosyn.experiments.results.summary import fmt
from geosyn.experiments.run.run_metrics import unit_of

#: Metrics drawn per grid axis, in this order (those the summaries have).
PLOTTED = (
    "rms_error",
    "max_error",
    "recovery_time",
    "effort",
    "mechanical_energy",
    "min_clearance",
    "min_mesh_clearance",
)


def _number(text: str) -> float | None:
    try:
        value = float(yaml.safe_load(str(text)))
    except (TypeError, ValueError, yaml.YAMLError):
        return None
    return value if math.isfinite(value) else None


def axis_plot(
    out: Path, axis: str, grid: dict[str, list[str]], rows: list[dict[str, Any]]
) -> Path | None:
    """``sweep_<axis>.png``: plotted metrics against the values of grid axis ``axis``.

    Returns:
        The file, or None when no plotted metric is in the summaries.
    """
    keys = list(dict.fromkeys(k for r in rows for k in r["metrics"]))
    names = [m for m in PLOTTED if any(k.rsplit(".", 1)[-1] == m for k in keys)]
    if not names:
        return None
    values = list(grid[axis])
    numeric = [_number(v) for v in values]
    xs = numeric if all(x is not None for x in numeric) else list(range(len(values)))
    others = [k for k in grid if k != axis]
    fig, axes = figure((6.5, 2.4 * len(names)), len(names), 1, squeeze=False, sharex=True)
    for ax, name in zip(axes[:, 0], names, strict=True):
        series = [k for k in keys if k.rsplit(".", 1)[-1] == name]
        line = 0
        for key in series:
            contexts = {tuple(r["point"].get(o) for o in others) for r in rows}
            for ctx in sorted(contexts, key=str):
                mean, std = [], []
                for v in values:
                    match = [
                        r
                        for r in rows
                        if r["point"].get(axis) == v
                        and tuple(r["point"].get(o) for o in others) == ctx
                    ]
                    m = match[0]["metrics"].get(key) if match else None
                    mean.append(m["mean"] if m else math.nan)
                    std.append(m["std"] if m else math.nan)
                label = key.rsplit(".", 1)[0] if "." in key else name
                if others:
                    label += (
                        " (" + ", ".join(f"{o}={c}" for o, c in zip(others, ctx, strict=True)) + ")"
                    )
                color = COLORS[line % len(COLORS)]
                ax.errorbar(xs, mean, yerr=std, marker="o", capsize=3, color=color, label=label)
                line += 1
        unit = unit_of(name)
        ax.set_ylabel(f"{name} [{unit}]" if unit else name)
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7)
    bottom = axes[-1, 0]
    bottom.set_xlabel(axis)
    if not all(x is not None for x in numeric):
        bottom.set_xticks(xs, values)
    fig.suptitle("mean ± std over seeds")
    return save(fig, out / f"sweep_{axis.replace('/', '_')}.png")


def report_sweep(out: str | Path, quiet: bool = False) -> list[dict[str, Any]]:
    """Rewrite a sweep directory's tables and draw one plot per grid axis.

    Returns:
        The aggregate rows (see `geosyn.experiments.results.aggregate.aggregate`).

    Raises:
        ExperimentError: not a sweep directory, or none of its runs is complete.
    """
    out = Path(out)
    spec_file = out / "sweep.yaml"
    if not spec_file.is_file():
        raise ExperimentError(f"sweep_dir {str(out)!r} has no sweep.yaml; is it a sweep directory?")
    spec = yaml.safe_load(spec_file.read_text())
    grid: dict[str, list[str]] = {str(k): [str(v) for v in vs] for k, vs in spec["grid"].items()}
    points = [dict(zip(grid, combo, strict=True)) for combo in itertools.product(*grid.values())]
    rows = aggregate(out, points, int(spec["seeds"]))
    if not any(r["n_runs"] for r in rows):
        raise ExperimentError(f"sweep_dir {str(out)!r} has no complete run yet")
    name = Path(str(spec["source"])).stem
    write_aggregate(out, name, rows)
    for axis in grid:
        axis_plot(out, axis, grid, rows)
    if not quiet:
        _print(name, rows)
    return rows


def _print(name: str, rows: list[dict[str, Any]]) -> None:
    table = Table(title=f"sweep {name}: mean ± std over seeds")
    table.add_column("metric")
    for r in rows:
        table.add_column(f"{point_name(r['point'])} (n={r['n_runs']})", justify="right")
    keys = list(dict.fromkeys(k for r in rows for k in r["metrics"]))
    for k in keys:
        unit = unit_of(k.rsplit(".", 1)[-1])
        cells = []
        for r in rows:
            m = r["metrics"].get(k)
            cells.append("" if m is None else f"{fmt(m['mean'])} ± {fmt(m['std'])}")
        table.add_row(escape(f"{k} [{unit}]" if unit else k), *cells)
    Console(width=max(Console().width, 120)).print(table)


__all__ = ["PLOTTED", "axis_plot", "report_sweep"]
