"""Sequences of geodesic synergies: continuity at the junctions, geodesic segments, energy."""

from __future__ import annotations

import json

import numpy as np
import pytest

from geosyn.experiments.procedures.common import geodesic_residual
from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.geodesic import exp
from geosyn.robots import load_robot
from geosyn.robots.kinematics import frame_position
from geosyn.synergies import InvalidSynergyInput, orthonormal_synergies
from geosyn.synergies.sequence import (
    geodesic_sequence,
    reach_sequence,
    straight_sequence,
    time_law,
)

#: Stated geodesic residual of a segment: max |d2q/ds2 + Gamma(q, dq/ds)| [rad] with
#: 4th-order differences of 200 RK4 samples; the differences' truncation h^4 |q^(6)|
#: dominates (h = 1/200, |dq/ds| up to 6 rad on the planar arm: ~3e-5).
RESIDUAL_TOL = 1e-4


@pytest.fixture(scope="module")
def planar():
    robot = load_robot("planar2")
    return robot, KineticEnergyMetric(robot)


@pytest.fixture(scope="module")
def sequence(planar):
    _, metric = planar
    W = np.array([[0.2, 0.3], [1.5, 1.8], [0.4, 2.2], [-0.6, 0.5]])
    return geodesic_sequence(metric, W, [1.0, 0.7, 1.3], steps=200)


def test_velocity_is_continuous_at_every_junction(sequence):
    jumps = sequence.junction_jumps()
    assert jumps.shape == (2, 3)
    assert np.all(jumps <= 1e-6)
    # one-sided limits by sampling just before and after each junction
    for tj in sequence.junction_times:
        (q_l, v_l, _), (q_r, v_r, _) = sequence.sample(tj - 1e-9), sequence.sample(tj + 1e-9)
        assert np.max(np.abs(v_l - v_r)) <= 1e-6
        assert np.max(np.abs(q_l - q_r)) <= 1e-6


def test_each_segment_satisfies_the_geodesic_equation(sequence, planar):
    _, metric = planar
    for seg in sequence.segments:
        # independent check: G(q) q'' + C(q, q') q' from 4th-order differences of the
        # samples (the experiments' residual, in [N m] here, metric of order 1 kg m^2)
        assert geodesic_residual(metric, seg.s, seg.q) <= RESIDUAL_TOL
        assert seg.geodesic_residual() <= RESIDUAL_TOL
    # it is truncation of the differences: twice the samples, ~16x less (4th order)
    fine = geodesic_sequence(metric, sequence.waypoints[:2], [1.0], steps=400).segments[0]
    assert fine.geodesic_residual() <= sequence.segments[0].geodesic_residual() / 10
    # the straight baseline through the same points is no geodesic
    lin = straight_sequence(sequence.waypoints, [1.0, 0.7, 1.3])
    lin_seg = lin.segments[0]
    lin_res = max(
        np.max(np.abs(metric.geodesic_acceleration(qk, dk)))
        for qk, dk in zip(lin_seg.q, lin_seg.dq, strict=True)
    )
    assert lin_res > 1e3 * RESIDUAL_TOL


def test_segments_join_the_waypoints_and_follow_the_time_law(sequence, planar):
    _, metric = planar
    W = sequence.waypoints
    np.testing.assert_allclose(W, [[0.2, 0.3], [1.5, 1.8], [0.4, 2.2], [-0.6, 0.5]], atol=1e-8)
    seg = sequence.segments[1]
    t = seg.t0 + 0.3 * seg.duration
    q, v, _ = sequence.sample(t)
    sigma, dsigma, _ = time_law(0.3)
    # position: the geodesic from the segment start at parameter sigma (independent exp)
    v0 = seg.dq[0]
    g = exp(metric, seg.q[0], v0 * sigma, duration=1.0, steps=400)
    np.testing.assert_allclose(q, g.q[-1], atol=1e-8)
    # velocity: the geodesic's velocity times d(sigma)/dt
    np.testing.assert_allclose(v, g.v[-1] / sigma * dsigma / seg.duration, atol=1e-7)
    # the sampled acceleration is the time derivative of the sampled velocity
    dt = 1e-5
    a_fd = (sequence.sample(t + dt)[1] - sequence.sample(t - dt)[1]) / (2 * dt)
    np.testing.assert_allclose(sequence.sample(t)[2], a_fd, atol=1e-4)
    # rest at the start, the junctions and the goal
    for tj in (0.0, *sequence.junction_times, sequence.duration):
        np.testing.assert_allclose(sequence.sample(tj)[1], 0.0, atol=1e-12)


def test_geodesic_sequence_needs_less_energy_than_straight_lines(sequence, planar):
    _, metric = planar
    lin = straight_sequence(sequence.waypoints, [1.0, 0.7, 1.3])
    e_geo, e_lin = sequence.energy(metric), lin.energy(metric)
    assert e_geo < e_lin
    # per segment at constant speed, the geodesic energy is 1/2 |v0|_G^2 / T
    seg = sequence.segments[0]
    e_const = 0.5 * seg.dq[0] @ metric.G(seg.q[0]) @ seg.dq[0] / seg.duration
    # the quintic law costs int sigma'^2 du = 10/7 times the constant-speed energy
    one = geodesic_sequence(metric, sequence.waypoints[:2], [seg.duration], steps=200)
    np.testing.assert_allclose(one.energy(metric, dt=1e-3), 10.0 / 7.0 * e_const, rtol=1e-6)


def test_reach_sequence_brings_the_hand_to_each_goal_with_transported_synergies():
    robot = load_robot("panda")
    metric = KineticEnergyMetric(robot)
    q0 = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
    basis = orthonormal_synergies(metric, q0, 3, frame=robot.ee_frame, robot=robot)
    targets = np.array([[0.45, 0.1, 0.4], [0.5, -0.1, 0.35]])
    seq = reach_sequence(list(basis.synergies), targets, robot.ee_frame, robot, [1.0, 1.0])
    fid = robot.frame_id(robot.ee_frame)
    for seg, p in zip(seq.segments, targets, strict=True):
        assert np.linalg.norm(frame_position(robot, seg.q[-1], fid) - p) <= 1e-4
        assert seg.reach_error <= 1e-4
        assert seg.geodesic_residual() <= RESIDUAL_TOL
    assert np.all(seq.junction_jumps() <= 1e-6)


def test_bad_input_names_the_argument(planar):
    _, metric = planar
    with pytest.raises(InvalidSynergyInput, match="durations"):
        geodesic_sequence(metric, [[0.0, 0.0], [1.0, 1.0]], [1.0, 2.0])
    with pytest.raises(InvalidSynergyInput, match="waypoints"):
        geodesic_sequence(metric, [[0.0, 0.0]], [])
    with pytest.raises(InvalidSynergyInput, match="durations"):
        straight_sequence([[0.0, 0.0], [1.0, 1.0]], [-1.0])


def test_builtin_synergy_sequence_saves_energy_and_keeps_clear(tmp_path):
    from geosyn.experiments import load_config, run_experiment

    cfg, _ = load_config("synergy_sequence", ["outputs.plots=false", "params.steps=100"])
    outcome = run_experiment(cfg, tmp_path / "seq", progress=False, quiet=True)
    s = json.loads((outcome.path / "summary.json").read_text())
    assert s["energy_saving"] > 0.0
    assert s["geodesic.energy"] < s["straight.energy"]
    assert s["max_velocity_jump"] <= 1e-6
    assert s["max_residual"] <= RESIDUAL_TOL
    assert s["max_reach_error"] <= 1e-4
    assert s["geodesic.ok"] == s["straight.ok"] == 1.0
    assert s["geodesic.final_hand_error"] <= 2e-3
    assert s["geodesic.min_clearance"] > 0.0 and s["straight.min_clearance"] > 0.0
    # the sphere collides in MuJoCo (scene.contact) and neither run touches it
    for path in ("geodesic", "straight"):
        assert s[f"{path}.max_contact_force"] == 0.0


def test_builtin_config_checks_one_duration_per_goal():
    from geosyn.experiments import load_config
    from geosyn.experiments.errors import ConfigError

    with pytest.raises(ConfigError, match=r"params.durations: one per target \(3\)"):
        load_config("synergy_sequence", ["params.durations=[1.0]"])
