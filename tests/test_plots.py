"""Plot helpers: what they detect (reference end, torque limits, log axes) against known
synthetic runs, and that the figures are written without touching pyplot's state."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from geosyn.experiments.results import plots
from geosyn.experiments.results.plots import (
    bar_plot,
    envelope,
    log_floor,
    reference_end,
    torque_limits,
    torque_plot,
    tracking_error_plot,
    use_log_axis,
)


def _run(t_end_ref: float = 1.5, limit: float = 5.0) -> dict[str, np.ndarray]:
    """A 2 s run at 10 ms ticks: the reference moves until ``t_end_ref`` then holds; joint
    0's torque is clipped at +-``limit`` between 0.5 and 0.7 s, joint 1 never."""
    t = np.arange(0.0, 2.0, 0.01)
    s = np.minimum(t, t_end_ref)
    q_ref = np.stack([np.sin(s), 0.5 * s], axis=1)
    q = q_ref - 1e-3 * np.exp(-t)[:, None]
    tau = np.stack([3.0 * np.sin(4 * t), np.cos(t)], axis=1)
    sat = np.zeros_like(tau, dtype=bool)
    window = (t >= 0.5) & (t < 0.7)
    tau[window, 0], sat[window, 0] = -limit, True
    return {"t": t, "q": q, "q_ref": q_ref, "tracking_error": q_ref - q,
            "tau_applied": tau, "saturated": sat}  # fmt: skip


def test_reference_end_is_the_first_held_sample():
    assert reference_end(_run(1.5)) == pytest.approx(1.5)  # q_ref(1.49) != q_ref(1.50) == end
    assert reference_end(_run(5.0)) is None  # moves to the end of the run
    nan = _run() | {"q_ref": np.full((200, 2), np.nan)}
    assert reference_end(nan) is None  # no reference


def test_torque_limits_are_the_clipped_values():
    lim = torque_limits(_run(limit=5.0))
    assert lim[0] == 5.0 and np.isnan(lim[1])


@pytest.mark.parametrize("block", [7, 64])
def test_reference_end_and_limits_a_block_at_a_time(block, monkeypatch):
    """A long run's log is read a block of ticks at a time: the same end and limits."""
    from geosyn.sim import blocks

    runs = [_run(1.5), _run(5.0), _run(limit=2.0)]
    whole = [(reference_end(r), torque_limits(r)) for r in runs]
    monkeypatch.setattr(blocks, "SCAN_BLOCK", block)
    for r, (end, lim) in zip(runs, whole, strict=True):
        assert reference_end(r) == end
        np.testing.assert_array_equal(torque_limits(r), lim)


def test_a_long_series_is_drawn_as_its_envelope(monkeypatch):
    """Up to PLOT_POINTS ticks the series itself; beyond, min and max per bucket: the
    extremes and a one-tick spike survive, in at most PLOT_POINTS points."""
    t = np.arange(100_000) * 1e-3
    y = np.stack([np.sin(t), np.cos(3 * t)], axis=1)
    y[54_321, 1] = 9.0  # a one-tick spike
    short_t, short_y = envelope(t[:500], y[:500])
    assert np.array_equal(short_t, t[:500]) and np.array_equal(short_y, y[:500])
    monkeypatch.setattr(plots.blocks, "SCAN_BLOCK", 1000)  # buckets across blocks
    te, ye = envelope(t, y)
    assert len(te) <= plots.PLOT_POINTS and ye.shape == (len(te), 2)
    assert np.all(np.diff(te) >= 0) and te[0] == 0.0
    np.testing.assert_array_equal(ye.max(axis=0), [y[:, 0].max(), 9.0])
    np.testing.assert_array_equal(ye.min(axis=0), y.min(axis=0))
    tn, norm = envelope(t, y, lambda a: np.linalg.norm(a, axis=1), points=1000)
    assert len(tn) <= 1000 and norm.max() == np.linalg.norm(y[54_321])


def test_log_floor_keeps_every_series_visible():
    values = [np.array([0.0, 3e-9, 1e-3]), np.array([2e-7, 1.0])]
    floor = log_floor(values)
    assert 1e-12 <= floor <= 3e-9
    assert log_floor([np.zeros(3)]) == 1e-6  # nothing positive: a default decade


def test_log_axis_when_the_point_is_a_ratio():
    assert use_log_axis([1.0, 4e4])  # e.g. residual geodesic vs linear
    assert not use_log_axis([1.0, 2.0])
    assert not use_log_axis([0.0, 4e4])  # a zero has no place on a log axis
    assert not use_log_axis([5.0])


def test_figures_are_written(tmp_path):
    """Each helper writes a PNG of the expected size; pyplot holds no figure afterwards."""
    runs = {"computed_torque": _run(), "qp": _run(limit=4.0)}
    windows = [(0.5, 0.7, "push")]
    paths = [
        tracking_error_plot(tmp_path / "e.png", runs, 1e-2, windows),
        torque_plot(tmp_path / "tau.png", runs, windows=windows),
        torque_plot(tmp_path / "tau_lim.png", runs, limits=np.array([5.0, 2.0])),
        bar_plot(tmp_path / "bar.png", ["geodesic", "linear"], [1e-8, 4e-4], "r [N m]", "r"),
    ]
    for p in paths:
        with Image.open(p) as im:
            assert im.size[0] > 400 and im.size[1] > 300
    import sys

    if "matplotlib.pyplot" in sys.modules:
        import matplotlib.pyplot as plt

        assert plt.get_fignums() == []
