"""Stance: contact frames held fixed, the induced metric and its geodesics
(geosyn.metrics.stance).

References: the held frames' poses (an invariant), energy conservation, d'Alembert's
principle (the constraint force does no work on tangent motions), and MuJoCo's own
simulation of the same file with the frame held by a weld equality, whose error must
shrink as the weld is made stiffer.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from floating_cases import FLOATER, floater_file, load_quietly

from geosyn.metrics import FloatingKineticEnergyMetric
from geosyn.metrics.errors import StanceError
from geosyn.metrics.stance import Stance
from geosyn.robots import UnknownFrame
from geosyn.robots.floating import from_mujoco, to_mujoco

FEET = ["left_sole_link", "right_sole_link"]


def talos_stance() -> tuple[Stance, np.ndarray, np.ndarray]:
    """TALOS holding both soles, and a tangent start (q, v)."""
    robot = load_quietly("talos_reduced")
    metric = FloatingKineticEnergyMetric(robot)
    q_ref = robot.neutral()
    q_ref[2] = 1.0
    stance = Stance(metric, FEET, q_ref)
    q, v = stance.project(q_ref, np.random.default_rng(26).normal(scale=0.3, size=robot.nv))
    return stance, q, v


def test_both_feet_stay_put_and_energy_is_conserved() -> None:
    stance, q0, v0 = talos_stance()
    metric = stance.metric
    assert stance.dimension == metric.n - 12 == 26
    geo = stance.geodesic(q0, v0, duration=1.0, steps=200)
    worst = max(float(np.abs(stance.residual(q)).max()) for q in geo.q)
    assert worst < 1e-8  # [m] and [rad], over 1 s (measured ~1e-13)
    drift = []
    for g in (stance.geodesic(q0, v0, duration=1.0, steps=100), geo):
        energy = np.array([metric.energy(q, v) for q, v in zip(g.q, g.v, strict=True)])
        drift.append(np.ptp(energy) / energy[0])
    # measured 7.9e-6 and 4.5e-7 (47 J): the integration error, falling as dt^4
    assert energy[0] > 10.0 and drift[1] < 1e-6 and drift[0] / drift[1] > 12.0
    assert np.linalg.norm(metric.difference(q0, geo.q[-1])) > 0.3  # the body moved


def test_the_constraint_force_does_no_work_on_tangent_motions() -> None:
    stance, q, v = talos_stance()
    metric = stance.metric
    a = stance.acceleration(q, v)
    force = metric.G(q) @ a + metric.coriolis(q, v)  # = J^T lambda
    N = stance.tangent_basis(q)
    assert N.shape == (metric.n, 26)
    assert np.abs(N.T @ force).max() < 1e-9 * np.abs(force).max()
    assert np.abs(stance.jacobian(q) @ v).max() < 1e-12
    z = np.linalg.lstsq(N, v, rcond=None)[0]  # v in tangent coordinates
    assert 0.5 * z @ stance.G(q) @ z == pytest.approx(metric.energy(q, v), rel=1e-12)


def test_matches_mujoco_with_a_weld_and_the_error_shrinks_as_it_stiffens(tmp_path) -> None:
    path = floater_file(tmp_path, dt=1e-4)
    metric = FloatingKineticEnergyMetric(load_quietly(path))
    q_ref, _ = from_mujoco(mujoco.MjModel.from_xml_path(str(path)).qpos0, np.zeros(metric.n))
    stance = Stance(metric, ["shin_l"], q_ref)  # MuJoCo's weld holds the initial pose
    q0, v0 = stance.project(q_ref, np.random.default_rng(1).normal(size=metric.n))
    geo = stance.geodesic(q0, v0, duration=1.0, steps=1000)
    errors = []
    for timeconst in (0.02, 0.004, 0.001):  # weld stiffness: MuJoCo's solref time constant
        weld = (
            f'<equality><weld body1="shin_l" solref="{timeconst} 1"'
            ' solimp="0.9999 0.9999 0.001"/></equality>'
        )
        m = mujoco.MjModel.from_xml_string(
            FLOATER.format(dt=1e-4).replace("</worldbody>", "</worldbody>" + weld)
        )
        d = mujoco.MjData(m)
        d.qpos[:], d.qvel[:] = to_mujoco(q0, v0)
        worst = 0.0
        for k in range(1, 11):
            while d.time < 0.1 * k - 1e-9:
                mujoco.mj_step(m, d)
            q_mj, _ = from_mujoco(d.qpos, d.qvel)
            worst = max(worst, float(np.abs(metric.difference(q_mj, geo.q[100 * k])).max()))
        errors.append(worst)
    # measured 9.5e-5, 3.8e-6, 2.4e-7
    assert errors[0] < 1e-4 and errors[1] < errors[0] / 10 and errors[2] < errors[1] / 5
    assert np.linalg.norm(metric.difference(q0, geo.q[-1])) > 0.5  # it moved


def test_bad_stances_are_one_clear_error_each() -> None:
    stance, q, v = talos_stance()
    metric = stance.metric
    with pytest.raises(UnknownFrame, match="'left_foot' is not in robot 'talos_reduced'"):
        Stance(metric, ["left_foot"], q)
    with pytest.raises(StanceError, match=r"over-constrains .* 12 constraints .* of rank 6"):
        Stance(metric, ["left_sole_link", "leg_left_sole_fix_joint"], q)  # one body
    solo = FloatingKineticEnergyMetric(load_quietly("solo12"))
    feet = ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"]
    with pytest.raises(StanceError, match=r"24 constraints .* on nv = 18"):
        Stance(solo, feet, solo.robot.neutral())
    with pytest.raises(StanceError, match="at least one frame"):
        Stance(metric, [], q)
    with pytest.raises(StanceError, match="held-frame velocity"):
        stance.geodesic(q, v + 0.1)
    moved = q.copy()
    moved[0] += 0.01
    with pytest.raises(StanceError, match="pose error 0.01"):
        stance.geodesic(moved, v)
