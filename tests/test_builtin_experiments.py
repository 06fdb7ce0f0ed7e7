"""The seven built-in experiments in smoke form, each with its physical claim asserted."""

from __future__ import annotations

import json

import numpy as np
import pytest

from geosyn.experiments import load_config, run_experiment
from geosyn.experiments.config.loader import builtin_names


def _run(name, tmp_path, *overrides, plots=False):
    cfg, _ = load_config(name, [f"outputs.plots={str(plots).lower()}", *overrides])
    outcome = run_experiment(cfg, tmp_path / name, progress=False, quiet=True)
    # NaN-aware equality: a run that did not complete has NaN metrics (NaN == NaN here)
    np.testing.assert_equal(
        json.loads((outcome.path / "summary.json").read_text()), outcome.summary
    )
    with np.load(outcome.path / "results.npz") as data:
        results = {k: np.array(data[k]) for k in data.files}
    return outcome.summary, results


def test_the_builtins_each_have_a_description():
    names = builtin_names()
    assert names == sorted(
        [
            "arm_synergy_combinations",
            "go2_body_shift",  # its claims: tests/test_floating_experiments.py
            "human_synergies",  # its claims: tests/test_human_experiment.py
            "perception_reach",  # its claims: tests/test_perception_map.py
            "pga_vs_pca",
            "pick_and_place",  # its claims: tests/test_pick_and_place.py
            "panda_obstacle_shaping",
            "panda_payload_shaping",
            "panda_push_recovery",
            "planar2_geodesic_vs_euclidean",
            "synergy_sequence",  # its claims: tests/test_sequence.py
            "synergy_transport",
            "talos_stance_push",  # its claims: tests/test_floating_experiments.py
            "ur5_tracking",  # kind tracking; its claims: tests/test_tracking.py
        ]
    )
    for name in names:
        cfg, _ = load_config(name)
        assert cfg.name == name and len(cfg.description) > 40


def test_planar2_geodesic_needs_less_effort_than_straight_line(tmp_path):
    s, r = _run("planar2_geodesic_vs_euclidean", tmp_path, "params.steps=100", plots=True)
    assert s["geodesic.ok"] == s["straight.ok"] == 1.0
    assert s["geodesic.effort"] < s["straight.effort"]
    # free motion: the geodesic needs (almost) no torque on the horizontal arm
    assert s["geodesic.effort"] < 1e-2 * s["straight.effort"]
    # the geodesic is the shorter path in energy (it minimises it between the end points)
    assert s["geodesic.path_energy"] < s["straight.path_energy"]
    # both paths join the same configurations
    for p in ("geodesic", "straight"):
        np.testing.assert_allclose(r[f"path_{p}__q"][-1], [1.4, -0.9], atol=1e-8)
    assert (
        tmp_path / "planar2_geodesic_vs_euclidean" / "figure1_configuration_space.png"
    ).is_file()


def test_arm_combinations_are_geodesics_pca_combinations_are_not(tmp_path):
    s, r = _run("arm_synergy_combinations", tmp_path)
    assert s["max_residual_geodesic"] <= 1e-6
    assert s["min_residual_pca_linear"] >= 100 * max(s["max_residual_geodesic"], 1e-6)
    # independent check of a linear residual: q = q0 + t u has qdd = 0 and the residual
    # is the Coriolis/centrifugal torque C(q, u) u, here at t = 0 (pinocchio's own C).
    import pinocchio as pin

    from geosyn.robots import load_robot

    robot = load_robot("talos_arm")
    q, t = r["linear0__q"], r["linear0__t"]
    u = (q[-1] - q[0]) / (t[-1] - t[0])
    data = robot.model.createData()
    C = pin.computeCoriolisMatrix(robot.model, data, q[2], u)
    assert np.linalg.norm(C @ u) <= s["w=(1.2,0.7).residual_pca_linear"] * (1 + 1e-9)


def test_transport_preserves_synergy_norms_and_geodesicity(tmp_path):
    s, _ = _run("synergy_transport", tmp_path, "params.steps=200")
    assert s["transported.norm_change"] < 1e-6
    assert s["naive.norm_change"] > 1e-3
    assert s["transported.residual"] <= 1e-6
    assert s["superposition.residual"] > 1e-2
    assert s["naive.endpoint_offset"] > 1e-3


def test_pga_reconstructs_geodesic_demonstrations_better_than_pca(tmp_path):
    s, r = _run("pga_vs_pca", tmp_path, "params.n_demos=12", "params.k_max=3")
    assert s["k=2.pga_error"] < s["k=2.pca_error"]
    assert np.all(np.diff(r["pca_error_joint"]) <= 1e-12)  # PCA error never grows with k
    assert s["k=1.pga_error"] > s["k=2.pga_error"]


@pytest.mark.slow
def test_payload_shaped_geodesic_has_less_true_energy(tmp_path):
    s, r = _run("panda_payload_shaping", tmp_path, "simulation.duration=1.5")
    assert s["shaped.ok"] == s["unshaped.ok"] == 1.0
    # the load-shaped metric is the plant's (robot + 2 kg) kinetic energy: its geodesic
    # has the least energy of that plant between the two configurations
    assert s["shaped.energy_shaped_metric"] < s["unshaped.energy_shaped_metric"]
    assert s["unshaped.energy_unshaped_metric"] < s["shaped.energy_unshaped_metric"]
    # the payload is attached in MuJoCo: 2 kg on top of the robot's mass
    assert np.all(r["shaped_computed_torque__payload_mass"] == 2.0)


@pytest.mark.slow
def test_obstacle_shaped_geodesic_keeps_clear(tmp_path):
    s, r = _run("panda_obstacle_shaping", tmp_path)
    assert s["shaped.planned_clearance"] > 0.0
    assert s["unshaped.planned_clearance"] < 0.0  # the obstacle is really in the way
    # the sphere collides in MuJoCo (scene.contact: true, on in this experiment): the
    # shaped run completes and never touches it ...
    assert s["shaped.ok"] == 1.0
    assert s["shaped.executed_clearance"] > 0.0
    assert s["shaped.max_contact_force"] == 0.0 and s["shaped.contact_time"] == 0.0
    assert np.all(r["shaped_computed_torque__contact_force"] == 0.0)
    # ... the unshaped one hits it: MuJoCo's contact solver reports a normal force (in
    # the run's log up to the stop when the hit stops the run; a stopped run's summary
    # metrics are NaN, never numbers that look like a result)
    force = r["unshaped_computed_torque__contact_force"]
    assert force.max() > 1.0  # [N]
    status = str(r["unshaped_computed_torque__status"])
    assert (s["unshaped.ok"] == 1.0) == (status == "ok")
    if status == "ok":
        assert s["unshaped.max_contact_force"] == force.max()
        assert s["unshaped.contact_time"] == np.count_nonzero(force > 0.0) * 1e-3  # [s]
    else:  # stopped after the hit: the contact is named as the cause
        assert "cause: the robot hit an obstacle" in status
        assert json.loads(str(r["unshaped_computed_torque__meta"]))["status"] == status
        assert np.isnan(s["unshaped.max_contact_force"]) and np.isnan(s["unshaped.contact_time"])


@pytest.mark.slow
def test_push_recovery_every_controller_recovers_within_one_second(tmp_path):
    s, r = _run("panda_push_recovery", tmp_path, "simulation.duration=1.8")
    labels = ["computed_torque", "qp", "mpc"]
    for label in labels:
        assert s[f"{label}.ok"] == 1.0
        assert s[f"{label}.max_error"] > s["threshold"]  # the push really disturbs
        assert s[f"{label}.rms_after_window"] < 1e-2
        assert s[f"{label}.recovery_time"] <= 1.0
        # independent: RMS over the ticks 1 s after the push, from the stored errors
        t, e = r[f"{label}__t"], r[f"{label}__tracking_error"]
        sel = t >= s["push_start"] + 1.0
        assert np.sqrt(np.mean(e[sel] ** 2)) == pytest.approx(
            s[f"{label}.rms_after_window"], rel=1e-12
        )
        # the payload changed during the run (0 kg -> 0.5 kg), unknown to the controller
        m = r[f"{label}__payload_mass"][:, 0]
        assert m[0] == 0.0 and m[-1] == 0.5
