"""The fitted map from target positions to synergy weights, and the built-in experiment."""

from __future__ import annotations

import json

import numpy as np
import pytest

from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.geodesic import exp
from geosyn.robots import load_robot
from geosyn.robots.kinematics import frame_position
from geosyn.synergies import InvalidSynergyInput, orthonormal_synergies
from geosyn.synergies.perception_map import SynergyMap, monomials


@pytest.fixture(scope="module")
def fitted():
    robot = load_robot("panda")
    metric = KineticEnergyMetric(robot)
    q0 = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
    basis = orthonormal_synergies(metric, q0, 3, frame=robot.ee_frame, robot=robot)
    smap = SynergyMap(list(basis.synergies), robot.ee_frame, robot, steps=50, degree=3)
    return robot, metric, smap.fit(400, 0.5, seed=0)


def test_samples_are_exact_reach_solutions(fitted):
    robot, metric, smap = fitted
    P, W = smap.sample(3, 0.5, seed=7)
    fid = robot.frame_id(robot.ee_frame)
    for p, w in zip(P, W, strict=True):
        g = exp(metric, smap.q_start, smap.V @ w, duration=1.0, steps=50)  # independent
        np.testing.assert_allclose(frame_position(robot, g.q[-1], fid), p, atol=1e-12)


def test_map_error_is_below_2_cm_before_refinement_and_refinement_reaches_the_target(fitted):
    robot, _, smap = fitted
    P, _ = smap.sample(30, 0.4, seed=11)  # held-out targets inside the fitted region
    errors = [smap.solve(p, bound=np.inf).map_error for p in P]
    assert max(errors) <= 0.02
    fid = robot.frame_id(robot.ee_frame)
    for p in P[:5]:
        sol = smap.solve(p, bound=1e-3, tol=1e-4)
        assert sol.error <= (1e-4 if sol.refined else 1e-3)
        hand = frame_position(robot, sol.trajectory.q[-1], fid)
        assert np.linalg.norm(hand - p) == pytest.approx(sol.error, abs=1e-9)


def test_a_warm_start_from_a_nearby_solve_keeps_its_refinement(fitted):
    _, _, smap = fitted
    P, _ = smap.sample(1, 0.4, seed=12)
    first = smap.solve(P[0], bound=0.0, tol=1e-6)
    moved = P[0] + np.array([0.003, -0.002, 0.001])
    warm = smap.solve(moved, bound=np.inf, prior=(P[0], first.weights))
    cold = smap.solve(moved, bound=np.inf)
    assert warm.map_error < 0.2 * cold.map_error


def test_monomials_and_errors():
    x = np.array([[2.0, 3.0]])
    np.testing.assert_allclose(monomials(x, 2), [[1.0, 2.0, 3.0, 4.0, 6.0, 9.0]])
    robot = load_robot("planar2")
    metric = KineticEnergyMetric(robot)
    basis = orthonormal_synergies(metric, np.array([0.3, 0.5]), 2, robot=robot)
    smap = SynergyMap(list(basis.synergies), robot.ee_frame, robot)
    with pytest.raises(InvalidSynergyInput, match="fit"):
        smap.weights([0.1, 0.2, 0.0])
    with pytest.raises(InvalidSynergyInput, match="degree"):
        SynergyMap(list(basis.synergies), robot.ee_frame, robot, degree=7)


@pytest.mark.slow
def test_builtin_perception_reach_reaches_moving_targets_seen_by_the_camera(tmp_path):
    from geosyn.experiments import load_config, run_experiment

    cfg, _ = load_config("perception_reach", ["outputs.plots=false", "params.n_targets=3"])
    outcome = run_experiment(cfg, tmp_path / "pr", progress=False, quiet=True)
    s = json.loads((outcome.path / "summary.json").read_text())
    assert s["ok_runs"] == 3.0
    assert s["success_rate"] == 100.0
    assert s["final_error_max"] <= 10.0  # [mm]
    assert s["perception_error_max"] <= 5.0  # [mm]
    assert s["map_error_max"] <= 20.0  # [mm], before refinement
    assert s["latency_median"] > 0.0  # measured (its target is reported, not asserted)
