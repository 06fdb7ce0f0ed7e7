"""Recovery time per disturbance window (`geosyn.experiments.run.run_metrics`): synthetic error
traces with known windows and known recovery times, and the UR5 case against an
independent run whose reference does not end."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from geosyn.experiments import load_config, run_experiment
from geosyn.experiments.run import build as B
from geosyn.experiments.run.run_metrics import (
    Window,
    disturbance_windows,
    recovery_times,
    reference_end,
    standard_metrics,
)
from geosyn.metrics import exp, log

DT = 1e-3
T = np.arange(0.0, 3.0, DT)


def _bump(start: float, amplitude: float, tau: float) -> np.ndarray:
    """An error excursion ``amplitude * exp(-(t - start) / tau)`` from ``start`` on [rad]."""
    out = np.zeros_like(T)
    sel = T >= start
    out[sel] = amplitude * np.exp(-(T[sel] - start) / tau)
    return out


def _first_tick_at_or_after(x: float) -> float:
    return float(T[np.searchsorted(T, x - 1e-12)])


def test_synthetic_windows_give_their_known_recovery_times():
    h = 0.01
    # push at 0.5 s: 0.1 rad decaying with 50 ms -> below h after 50 ms * ln(10)
    # payload change at 1.5 s: 0.05 rad decaying with 100 ms -> after 100 ms * ln(5)
    # the reference ends moving at 2.2 s: a 0.05 rad excursion that is nobody's recovery
    err = _bump(0.5, 0.1, 0.05) + _bump(1.5, 0.05, 0.1) + _bump(2.2, 0.05, 0.1)
    windows = [Window(0, "push", 0.5, 0.6), Window(1, "payload_change", 1.5, 1.5)]
    got = recovery_times(T, err, windows, h, reference_stop=2.2)
    # known: the first tick at which the closed form is back below h, minus the start
    want = [
        _first_tick_at_or_after(0.5 + 0.05 * math.log(10.0)) - 0.5,
        _first_tick_at_or_after(1.5 + 0.1 * math.log(5.0)) - 1.5,
    ]
    np.testing.assert_allclose(got, want, atol=DT + 1e-12)
    np.testing.assert_allclose(want, [0.05 * math.log(10.0), 0.1 * math.log(5.0)], atol=DT)
    # counting the end of the reference (no stop given) makes the payload window's
    # recovery run to the end excursion: the error this module exists to avoid
    naive = recovery_times(T, err, windows, h)
    assert naive[1] > 0.7 + 0.1 * math.log(5.0) - DT


def test_no_excursion_is_zero_and_an_unfinished_one_is_inf():
    h = 0.01
    windows = [Window(0, "push", 0.5, 0.6), Window(1, "push", 1.0, 1.1)]
    # nothing after the first push; the second one never decays before the run ends
    err = np.where(T >= 1.0, 0.5, 0.0)
    assert recovery_times(T, err, windows, h) == [0.0, math.inf]
    # a window that starts after the run: not measured
    assert math.isnan(recovery_times(T, err, [Window(0, "push", 5.0, 5.1)], h)[0])


def test_the_next_window_closes_the_previous_one():
    h = 0.01
    # the push at 0.5 s has not recovered when the push at 0.52 s arrives
    err = _bump(0.5, 1.0, 0.05)
    windows = [Window(0, "push", 0.5, 0.51), Window(1, "push", 0.52, 0.53)]
    first, second = recovery_times(T, err, windows, h)
    assert first == math.inf
    assert second == pytest.approx(0.5 + 0.05 * math.log(100.0) - 0.52, abs=DT)


def test_reference_end_time_and_speed():
    # a reference moving at 0.4 rad/s on two joints until 1.2 s, then held
    q_ref = np.zeros((len(T), 2))
    moving = np.minimum(T, 1.2)
    q_ref[:, 0] = 0.4 * moving
    q_ref[:, 1] = -0.3 * moving
    stop, speed = reference_end(T, q_ref)
    assert stop == pytest.approx(1.2, abs=DT)
    assert speed == pytest.approx(0.5, rel=1e-9)  # ||(0.4, -0.3)|| rad/s
    # rest-to-rest (quintic) ends at rest: its end is found but its speed is ~0
    u = np.clip(T / 1.2, 0.0, 1.0)
    q_rest = (10 * u**3 - 15 * u**4 + 6 * u**5)[:, None]
    stop, speed = reference_end(T, q_rest)
    assert stop <= 1.2 + DT and speed < 1e-3
    # a reference moving to the end, or none at all: no end
    assert reference_end(T, T[:, None])[0] == math.inf
    assert reference_end(T, np.full((len(T), 2), np.nan))[0] == math.inf


def test_standard_metrics_use_the_logged_reference_end():
    h = 0.01
    q_ref = np.minimum(T, 2.2)[:, None] * np.ones((1, 2))  # ends moving (1.41 rad/s) at 2.2 s
    err = _bump(0.5, 0.1, 0.05) + _bump(2.2, 0.05, 0.1)
    e = np.stack([err, np.zeros_like(err)], axis=1)
    run = {
        "t": T,
        "q": q_ref - e,
        "q_ref": q_ref,
        "tracking_error": e,
        "v": np.ones((len(T), 2)),
        "tau_applied": np.full((len(T), 2), 2.0),
        "saturated": np.zeros((len(T), 2), bool),
        "clearance": np.linspace(0.3, 0.1, len(T)),
        "status": np.array("ok"),
    }
    pushes = [SimpleNamespace(type="push", start=0.5, duration=0.1)]
    m = standard_metrics(run, DT, disturbance_windows(pushes), h)
    assert m["recovery_time_d0"] == pytest.approx(0.05 * math.log(10.0), abs=DT)
    assert m["recovery_time"] == m["recovery_time_d0"]
    assert m["max_error"] == pytest.approx(0.1, abs=1e-12)
    n = len(T)
    assert m["effort"] == pytest.approx(n * 8.0 * DT, rel=1e-12)  # ||(2, 2)||^2 per tick
    assert m["mechanical_energy"] == pytest.approx(n * 4.0 * DT, rel=1e-12)  # |tau . v|
    assert m["min_clearance"] == pytest.approx(0.1)
    assert m["ok"] == 1.0 and m["saturations"] == 0.0


@pytest.mark.parametrize("block", [7, 600, 1201])
def test_metrics_a_block_at_a_time_are_the_whole_arrays_ones(block, monkeypatch):
    """A spooled log is reduced a block of ticks at a time (`geosyn.sim.blocks`): blocks
    of 7, 600 (the reference's last move ends a block) and 1201 ticks give the counts,
    extremes, recovery times and reference end of the whole arrays, the sums to rounding."""
    from geosyn.sim import blocks

    q_ref = np.minimum(T, 1.2)[:, None] * np.array([[0.4, -0.3]])
    e = np.stack([_bump(0.5, 0.1, 0.05) + _bump(1.5, 0.05, 0.1), 0.01 * np.sin(T)], axis=1)
    rng = np.random.default_rng(4)
    run = {
        "t": T,
        "q_ref": q_ref,
        "tracking_error": e,
        "v": rng.normal(size=(len(T), 2)),
        "tau_applied": rng.normal(size=(len(T), 2)),
        "saturated": rng.random((len(T), 2)) < 0.1,
        "fallback_used": rng.random(len(T)) < 0.05,
        "contact_force": np.abs(rng.normal(size=len(T))),
        "clearance": np.linspace(0.3, 0.1, len(T)) + 0.01 * np.sin(40 * T),
        "status": np.array("ok"),
    }
    pushes = [SimpleNamespace(type="push", start=s, duration=0.1) for s in (0.5, 1.5)]
    windows = disturbance_windows(pushes)
    whole, end = standard_metrics(run, DT, windows, 0.01), reference_end(T, q_ref)
    monkeypatch.setattr(blocks, "SCAN_BLOCK", block)
    assert reference_end(T, q_ref) == end
    parts = standard_metrics(run, DT, windows, 0.01)
    assert parts.keys() == whole.keys()
    for name, value in whole.items():
        if name in ("rms_error", "effort", "mechanical_energy"):
            assert parts[name] == pytest.approx(value, rel=1e-13), name
        else:
            assert parts[name] == value, name


@pytest.mark.slow
def test_ur5_recovery_matches_a_run_whose_reference_does_not_end(tmp_path):
    """The UR5 example: the reference ends moving 1 s after the push. The true recovery
    is measured on an independent run along the same geodesic integrated twice as long
    (same step, so the same samples up to 1.5 s: identical runs until then), where no
    end of reference follows the push."""
    cfg, _ = load_config("ur5_tracking", ["outputs.plots=false"])
    out = run_experiment(cfg, tmp_path / "run", progress=False, quiet=True)
    reported = out.summary["qp.recovery_time_d0"]

    robot = B.build_robot(cfg)
    metric = B.build_metric(cfg, robot)
    ref = cfg.reference
    q0, q1 = np.array(ref.q_start), np.array(ref.goal)
    v0 = log(metric, q0, q1, steps=ref.steps) / ref.duration
    longer = exp(metric, q0, v0, 2.0 * ref.duration, 2 * ref.steps)
    reference = B.tracked_reference(longer, metric, ref.time_scale)
    ctrl = B.build_controller(cfg.controllers[0], robot, metric, cfg.simulation.control_dt)
    res = B.simulate(cfg, robot, ctrl, reference, *reference.sample(0.0)[:2])
    norm = np.linalg.norm(res.tracking_error, axis=1)
    push = cfg.disturbances[0]
    above = np.nonzero((res.t >= push.start) & (norm > 0.01))[0]
    true = float(res.t[above[-1] + 1] - push.start)
    assert above[-1] + 1 < len(res.t) and true < 0.5  # it did recover, long before the end
    assert abs(reported - true) <= 0.05
    # counting the end of the reference (the former definition) is far off
    with np.load(out.path / "results.npz") as data:
        t, e = data["qp__t"], np.linalg.norm(data["qp__tracking_error"], axis=1)
    late = np.nonzero((t >= push.start) & (e > 0.01))[0][-1]
    assert t[late + 1] - push.start > true + 0.5
