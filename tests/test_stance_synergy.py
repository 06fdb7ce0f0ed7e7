"""Synergies on a stance (geosyn.metrics.stance_synergy) and their timing
(geosyn.controllers.whole_body_reference).

References: the held frames' poses (an invariant), the induced metric's energy (conserved
along its geodesic), finite differences of the samples, and the stance's tangent space.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from floating_cases import load_quietly

from geosyn.controllers.whole_body_reference import StanceSynergyReference
from geosyn.metrics import FloatingKineticEnergyMetric
from geosyn.metrics.errors import StanceError
from geosyn.metrics.stance import Stance
from geosyn.metrics.stance_synergy import StanceSynergy

FEET = ["left_sole_link", "right_sole_link"]


def talos_synergy() -> StanceSynergy:
    """Lower and shift the base while the right arm lifts, both soles held."""
    robot = load_quietly("talos_reduced")
    metric = FloatingKineticEnergyMetric(robot)
    q0 = robot.neutral()
    q0[2] = 1.0
    q0[7:] += np.random.default_rng(26).uniform(-0.2, 0.2, robot.nq - 7)
    direction = np.zeros(robot.nv)
    direction[1], direction[2] = 0.06, -0.06
    direction[6 + 22 : 6 + 26] = [0.3, -0.8, 0.2, -0.8]  # right shoulder and elbow
    return StanceSynergy(Stance(metric, FEET, q0), q0, direction, steps=50)


def test_frames_stay_put_and_the_energy_is_conserved_between_samples() -> None:
    syn = talos_synergy()
    stance, metric = syn.stance, syn.stance.metric
    points = [syn.at(s) for s in np.linspace(0.0, 1.0, 37)]  # between the stored samples
    assert max(np.abs(stance.residual(p.q)).max() for p in points) < 1e-8  # measured ~1e-14
    assert max(np.abs(stance.jacobian(p.q) @ p.dq).max() for p in points) < 1e-10
    energy = np.array([metric.energy(p.q, p.dq) for p in points])
    assert np.ptp(energy) / energy[0] < 1e-7 and energy[0] > 0.3  # measured 4.4e-9 (0.57 J)
    assert np.linalg.norm(metric.difference(points[0].q, points[-1].q)) > 0.8  # it moved


def test_samples_agree_with_finite_differences() -> None:
    syn = talos_synergy()
    model = syn.stance.robot.model
    h = 1e-4
    for s in (0.13, 0.5, 0.871):
        p, lo, hi = syn.at(s), syn.at(s - h), syn.at(s + h)
        dq_fd = pin.difference(model, lo.q, hi.q) / (2 * h)
        ddq_fd = (hi.dq - lo.dq) / (2 * h)  # velocity coordinates: left-trivialised
        assert np.abs(dq_fd - p.dq).max() < 1e-6 * np.abs(p.dq).max()  # measured ~1e-9
        assert np.abs(ddq_fd - p.ddq).max() < 1e-4 * np.abs(p.ddq).max()


def test_the_direction_is_projected_onto_the_stance() -> None:
    syn = talos_synergy()
    stance = syn.stance
    q0 = syn.geodesic.q[0]
    M, J = stance.metric.G(q0), stance.jacobian(q0)
    direction = syn.v0 + np.linalg.solve(M, J.T @ np.arange(1.0, 13.0))  # + a normal part
    again = StanceSynergy(stance, q0, direction, steps=50)
    assert np.abs(again.v0 - syn.v0).max() < 1e-10 * np.abs(syn.v0).max()
    with pytest.raises(StanceError, match="has no part tangent"):
        StanceSynergy(stance, q0, np.linalg.solve(M, J.T @ np.ones(12)))
    moved = q0.copy()
    moved[0] += 0.01
    with pytest.raises(StanceError, match=r"pose error 0.0099"):
        StanceSynergy(stance, moved, syn.v0)


def test_the_reference_starts_and_stops_at_rest_and_is_consistent() -> None:
    syn = talos_synergy()
    ref = StanceSynergyReference(syn, duration=1.5, t0=0.2)
    model = syn.stance.robot.model
    for t in (0.0, 0.2, 1.7, 2.5):
        sample = ref.sample(t)
        assert np.abs(sample.v).max() < 1e-12 and np.abs(sample.a).max() < 1e-12
    assert np.abs(pin.difference(model, ref.sample(2.5).q, ref.goal())).max() < 1e-12
    h = 1e-5
    for t in (0.4, 0.95, 1.5):
        lo, mid, hi = ref.sample(t - h), ref.sample(t), ref.sample(t + h)
        v_fd = pin.difference(model, lo.q, hi.q) / (2 * h)
        a_fd = (hi.v - lo.v) / (2 * h)
        assert np.abs(v_fd - mid.v).max() < 1e-6 * np.abs(mid.v).max()
        assert np.abs(a_fd - mid.a).max() < 1e-4 * np.abs(mid.a).max()
        assert np.abs(syn.stance.residual(mid.q)).max() < 1e-8
