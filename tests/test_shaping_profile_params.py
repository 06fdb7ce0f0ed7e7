"""The obstacle term's gain and cutoff are parameters of its compiled functions: terms that
differ only in them share one compiled library (a sweep over the gain compiles once), and
each gives its own barrier (reference: the pulled-back barrier written out in numpy,
`test_shaping_obstacle._reference_G`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_shaping_obstacle import _random_clear_q, _reference_G

from conftest import get_metric, get_robot
from geosyn.core import library_cache
from geosyn.metrics.geodesic.exp_map import numpy_rk4, rk4_step
from geosyn.metrics.shaping import ObstacleTerm, ShapedMetric
from geosyn.world import Sphere


def test_terms_differing_in_gain_and_cutoff_share_their_compiled_code(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """planar2, one sphere: the RK4 step of the second (gain, cutoff) is not compiled again;
    each term's G equals its own closed form (1e-6 relative) and each step its metric's
    numpy RK4 (1e-12); the two barriers differ."""
    monkeypatch.setenv("GEOSYN_CACHE_DIR", str(tmp_path))
    runs: list[Path] = []
    real = library_cache.run_compiler

    def counting(compiler, flags, source, output):  # type: ignore[no-untyped-def]
        runs.append(source)
        return real(compiler, flags, source, output)

    monkeypatch.setattr(library_cache, "run_compiler", counting)
    robot, base = get_robot("planar2"), get_metric("planar2")
    obstacles = [Sphere((0.55, 0.45, 0.0), 0.08)]
    rng = np.random.default_rng(7)
    Gs, compiles = [], []
    for gain, cutoff in ((1e-3, 0.2), (4e-3, 0.35)):
        term = ObstacleTerm(obstacles, capacity=1, gain=gain, cutoff=cutoff)
        shaped = ShapedMetric(base, [term])
        step = rk4_step(shaped)
        assert step is not None
        compiles.append(len(runs))
        checked = 0
        for _ in range(40):
            q = _random_clear_q(robot, term, rng)
            ref = _reference_G(robot, q, obstacles, gain, cutoff)
            if np.abs(ref).max() < 1e-6:
                continue
            np.testing.assert_allclose(term.G(q), ref, rtol=1e-6, atol=1e-9 * np.abs(ref).max())
            checked += 1
        assert checked >= 5
        q0, v0 = np.array([0.3, 0.9]), np.array([0.8, -0.4])
        x1 = np.asarray(step(np.concatenate([q0, v0]), np.r_[0.01, shaped.parameter_values()]))
        np.testing.assert_allclose(
            x1.ravel(), numpy_rk4(shaped, q0, v0, 0.01, 1)[-1], rtol=0, atol=1e-12
        )
        Gs.append(term.G(q0))
    assert compiles[0] >= 1 and compiles[1] == compiles[0]  # no compile for the second
    assert not np.allclose(Gs[0], Gs[1])


def test_set_profile_changes_the_barrier_without_a_rebuild() -> None:
    """`set_profile` on a built shaped metric: its G minus the base's equals the closed form
    of the new gain and cutoff (1e-6 relative), with no rebuild; a cutoff below d_min is
    refused and changes nothing."""
    from geosyn.metrics.shaping import InvalidTermArgument

    robot, base = get_robot("planar2"), get_metric("planar2")
    obstacles = [Sphere((0.55, 0.45, 0.0), 0.08)]
    term = ObstacleTerm(obstacles, capacity=1, gain=1e-3, cutoff=0.2)
    shaped = ShapedMetric(base, [term])
    rng = np.random.default_rng(8)
    qs = [_random_clear_q(robot, term, rng) for _ in range(30)]
    shaped.G(qs[0])
    builds = shaped.build_count
    term.set_profile(gain=4e-3, cutoff=0.35)
    checked = 0
    for q in qs:
        ref = _reference_G(robot, q, obstacles, 4e-3, 0.35)
        if np.abs(ref).max() < 1e-6:
            continue
        np.testing.assert_allclose(
            shaped.G(q) - base.G(q), ref, rtol=1e-6, atol=1e-9 * np.abs(ref).max()
        )
        checked += 1
    assert checked >= 5 and shaped.build_count == builds
    before = shaped.parameter_values().copy()
    with pytest.raises(InvalidTermArgument, match="cutoff"):
        term.set_profile(gain=2e-3, cutoff=1e-5)
    np.testing.assert_array_equal(shaped.parameter_values(), before)
    assert (term.gain, term.cutoff) == (4e-3, 0.35)
