"""JointLimitTerm: closed form, and geodesics aimed at a limit never cross it."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import get_metric, get_robot
from geosyn.metrics.geodesic import exp
from geosyn.metrics.shaping import InvalidTermArgument, JointLimitTerm, ShapedMetric

MARGIN, GAIN = 0.3, 0.1


def _phi(d: np.ndarray) -> np.ndarray:
    return np.where(d < MARGIN, (1.0 / np.maximum(d, 1e-12) - 1.0 / MARGIN) ** 2, 0.0)


def test_closed_form_diagonal_barrier() -> None:
    robot = get_robot("panda")
    term = JointLimitTerm(MARGIN, GAIN).bind(robot)
    rng = np.random.default_rng(40)
    inside = near = 0
    for _ in range(50):
        q = robot.random_q(rng)
        ref = GAIN * (_phi(q - robot.q_min) + _phi(robot.q_max - q))
        G = term.G(q)
        np.testing.assert_allclose(G, np.diag(ref), rtol=1e-13, atol=0.0)
        inside += int(np.sum(ref == 0.0))
        near += int(np.sum(ref > 0.0))
    assert inside > 0 and near > 0
    # Unlimited joints (planar2) get nothing.
    free = JointLimitTerm(MARGIN, GAIN).bind(get_robot("planar2"))
    assert np.array_equal(free.G(np.array([3.0, -3.0])), np.zeros((2, 2)))


def test_barrier_grows_like_inverse_square() -> None:
    robot = get_robot("panda")
    term = JointLimitTerm(MARGIN, GAIN).bind(robot)
    q = robot.neutral()
    w = []
    for d in (1e-2, 1e-3, 1e-4):
        q[3] = robot.q_max[3] - d
        w.append(term.G(q)[3, 3])
    assert 95 < w[1] / w[0] < 110 and 99 < w[2] / w[1] < 101


def test_exp_aimed_at_a_limit_never_crosses_it() -> None:
    """10 seeded geodesics on panda whose unshaped version crosses a limit by >= 0.1 rad."""
    robot = get_robot("panda")
    base = get_metric("panda")
    shaped = ShapedMetric(base, [JointLimitTerm(MARGIN, GAIN)])
    rng = np.random.default_rng(30)
    for trial in range(10):
        j = trial % 7
        q0 = robot.random_q(rng, margin=0.5)
        limit = robot.q_max[j] if trial % 2 == 0 else robot.q_min[j]
        v0 = 0.2 * rng.normal(size=7)
        v0[j] = 1.5 * (limit - q0[j])  # a straight line would reach the limit at t = 2/3
        free = exp(base, q0, v0, duration=1.0, steps=200)
        crossed = np.maximum(free.q - robot.q_max, robot.q_min - free.q).max()
        assert crossed > 0.1, (trial, crossed)
        g = exp(shaped, q0, v0, duration=1.0, steps=200)
        margin = np.minimum(robot.q_max - g.q, g.q - robot.q_min).min()
        assert margin > 0.0, (trial, margin)
        # The integration is accurate (energy conserved to 1 %), so staying inside is a
        # property of the geodesic, not of a lucky integration error.
        energy = np.array([shaped.energy(q, v) for q, v in zip(g.q, g.v, strict=True)])
        assert np.ptp(energy) <= 1e-2 * energy[0]


def test_bad_arguments() -> None:
    with pytest.raises(InvalidTermArgument, match="margin"):
        JointLimitTerm(margin=0.0)
    with pytest.raises(InvalidTermArgument, match="gain"):
        JointLimitTerm(gain=-1.0)
    with pytest.raises(InvalidTermArgument, match="d_min"):
        JointLimitTerm(margin=0.1, d_min=0.2)
    with pytest.raises(InvalidTermArgument, match="half the position range"):
        ShapedMetric(get_metric("panda"), [JointLimitTerm(margin=1.6)])
