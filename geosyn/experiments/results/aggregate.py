"""The aggregate of a sweep directory: per grid point, mean and std over seeds of every
scalar of the runs' ``summary.json`` (``sweep_summary.json``, ``sweep_summary.md``).

Written by `geosyn.experiments.sweep` at the end of a sweep and by ``geosyn report``
(`geosyn.experiments.results.report_sweep`).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from geosyn.experiments.results.summary import fmt
from geosyn.experiments.run.run_metrics import unit_of


def point_name(point: dict[str, str]) -> str:
    """Directory name of a grid point, ``key=value__key=value`` with unsafe characters replaced."""
    if not point:
        return "base"
    text = "__".join(f"{k}={v}" for k, v in point.items())
    return re.sub(r"[^A-Za-z0-9_.=,\-]", "_", text)[:200]


def aggregate(out: Path, points: Sequence[dict[str, str]], seeds: int) -> list[dict[str, Any]]:
    """Mean and std (over seeds) of each summary scalar, per grid point.

    NaN values (metrics of runs that did not complete, see
    `geosyn.experiments.results.summary.clean_summary`) are left out of the mean and std; ``n`` per
    metric says how many runs entered them, ``n_failed`` per point how many runs had a
    failed (diverged, stopped) controller run.
    """
    rows = []
    for point in points:
        summaries = []
        for s in range(seeds):
            path = out / point_name(point) / f"seed{s}" / "summary.json"
            if path.is_file():
                summaries.append(json.loads(path.read_text()))
        keys = list(dict.fromkeys(k for summ in summaries for k in summ))
        metrics = {}
        for k in keys:
            vals = np.array([float(summ[k]) for summ in summaries if k in summ])
            vals = vals[~np.isnan(vals)]  # NaN: not measured (a failed run), left out
            with np.errstate(invalid="ignore"):  # inf values (never recovered): std is nan
                metrics[k] = {
                    "mean": float(np.mean(vals)) if vals.size else math.nan,
                    "std": float(np.std(vals)) if vals.size else math.nan,
                    "n": int(vals.size),
                }
        n_failed = sum(1 for summ in summaries if float(summ.get("failed_runs", 0.0)) > 0)
        rows.append(
            {"point": point, "n_runs": len(summaries), "n_failed": n_failed, "metrics": metrics}
        )
    return rows


def write_aggregate(out: Path, name: str, rows: list[dict[str, Any]]) -> None:
    """``sweep_summary.json`` (the rows) and ``sweep_summary.md`` (mean ± std, with units)."""
    (out / "sweep_summary.json").write_text(json.dumps(rows, indent=1, allow_nan=True) + "\n")
    keys = list(dict.fromkeys(k for r in rows for k in r["metrics"]))
    lines = [
        f"# sweep: {name}",
        "",
        "mean ± std over seeds per grid point; runs that failed (diverged, stopped) do not"
        " enter the metrics they did not measure",
        "",
    ]
    lines.append(
        "| metric | "
        + " | ".join(
            point_name(r["point"]) + f" (n={r['n_runs']}, failed={r.get('n_failed', 0)})"
            for r in rows
        )
        + " |"
    )
    lines.append("|---|" + "---|" * len(rows))
    for k in keys:
        cells = []
        for r in rows:
            m = r["metrics"].get(k)
            cells.append("" if m is None else f"{fmt(m['mean'])} ± {fmt(m['std'])}")
        unit = unit_of(k.rsplit(".", 1)[-1])
        lines.append(f"| {k} [{unit}] | " if unit else f"| {k} | ")
        lines[-1] += " | ".join(cells) + " |"
    (out / "sweep_summary.md").write_text("\n".join(lines) + "\n")


__all__ = ["aggregate", "point_name", "write_aggregate"]
