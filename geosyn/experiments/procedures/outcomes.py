"""How every procedure counts failures: one stored status per run.

A run is a closed-loop simulation, or one trial of a procedure that reports per trial
(a target of ``perception_reach``). Its stored ``{prefix}__status`` is ``"ok"`` or why it
failed: the simulation's own reason (`geosyn.experiments.run.build.sim_arrays`: diverged,
stopped, controller failed), then those the procedure adds with `fail_run` (a target
missed beyond the procedure's tolerance, contact with an obstacle the plan avoids, ...),
joined by ``"; "``. Each run gives its summary row an ``ok`` (`Procedure.full_summary`
for runs stored with their arrays, `status_oks` for runs stored by their status only);
`geosyn.experiments.results.summary.clean_summary` counts the rows whose ``ok`` is not 1
(``failed_runs``) and marks every derived claim not established, and the runner prints
each failed run's status.
"""

from __future__ import annotations

import json
from collections.abc import Mapping

import numpy as np

from geosyn.sim.log import RUN_META

#: Suffix of a run's status in the results.
STATUS = "__status"


def run_status(results: Mapping[str, np.ndarray], prefix: str) -> str:
    """The stored status of run ``prefix`` (``"ok"`` or the reasons it failed)."""
    return str(results[prefix + STATUS])


def fail_run(results: dict[str, np.ndarray], prefix: str, reason: str) -> None:
    """Mark run ``prefix`` failed for ``reason`` (appended to a status already not ok).

    Updates ``{prefix}__status`` (created when the run stores nothing else) and the
    status in the run's metadata (``{prefix}__meta``, what `geosyn.sim.SimResult.load`
    reads) when it has one.
    """
    key = prefix + STATUS
    old = str(results[key]) if key in results else "ok"
    status = reason if old == "ok" else f"{old}; {reason}"
    results[key] = np.array(status)
    meta = prefix + RUN_META
    if meta in results:
        results[meta] = np.array(json.dumps(json.loads(str(results[meta])) | {"status": status}))


def status_oks(results: Mapping[str, np.ndarray], rows: Mapping[str, str]) -> dict[str, float]:
    """``{row}.ok`` (1.0 or 0.0) of each run ``prefix`` in ``rows`` (``{prefix: row}``)."""
    return {f"{row}.ok": float(run_status(results, p) == "ok") for p, row in rows.items()}


def contact_reason(run: Mapping[str, np.ndarray]) -> str | None:
    """Why a run that should not touch the scene's obstacles failed (its first contact
    and largest contact force), or None.

    Args:
        run: the run's arrays by field name (``t`` (T,) [s], ``contact_force`` (T,) [N],
            logged with ``scene.contact: true``).
    """
    force = np.asarray(run.get("contact_force", np.zeros(0)), dtype=np.float64)
    if not force.size or not (force > 0.0).any():
        return None
    first = int(np.argmax(force > 0.0))
    return (
        f"contact with an obstacle from t={float(run['t'][first]):.4g} s, force up to"
        f" {float(force.max()):.4g} N"
    )


__all__ = ["STATUS", "contact_reason", "fail_run", "run_status", "status_oks"]
