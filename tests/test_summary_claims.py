"""A summary with a failed run never states a derived claim (issue 21: a diverged run still
printed a 28 % energy saving)."""

from __future__ import annotations

import math

from geosyn.experiments.results.summary import clean_summary


def _summary(load_aware_ok: float) -> dict[str, float]:
    return {
        "load_aware.ok": load_aware_ok,
        "load_aware.energy": 1.44,
        "unloaded.ok": 1.0,
        "unloaded.energy": 2.0,
        "energy_saving_vs_unloaded": 28.0,
        "effort_ratio_straight_over_geodesic": 1.3,
        "peak_torque_reduction": 12.0,
        "reference_end": 2.0,
    }


def test_a_failed_run_marks_every_derived_claim_not_established() -> None:
    out = clean_summary(_summary(0.0))
    assert out["failed_runs"] == 1.0 and out["claims_established"] == 0.0
    for key in (
        "energy_saving_vs_unloaded",
        "effort_ratio_straight_over_geodesic",
        "peak_torque_reduction",
        "load_aware.energy",
    ):
        assert math.isnan(out[key]), key
    assert out["unloaded.energy"] == 2.0 and out["reference_end"] == 2.0  # not claims


def test_all_runs_ok_keep_their_claims() -> None:
    out = clean_summary(_summary(1.0))
    assert out["failed_runs"] == 0.0 and out["claims_established"] == 1.0
    assert out["energy_saving_vs_unloaded"] == 28.0 and out["peak_torque_reduction"] == 12.0
