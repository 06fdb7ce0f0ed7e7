"""Transfer of a hand path to the Panda: kinematic retargeting vs the geodesic between its ends."""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin
import pytest

from geosyn.metrics import KineticEnergyMetric
from geosyn.robots import load_robot
from geosyn.synergies.errors import InvalidSynergyInput
from geosyn.synergies.human import transfer as tr

HOME = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])


@pytest.fixture(scope="module")
def panda():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_robot("panda")


def test_hand_map_is_a_scaled_rigid_map(panda) -> None:
    rng = np.random.default_rng(11)
    wrist = rng.normal(0, 0.1, (50, 3)) + [0.0, 0.0, -0.5]
    shoulder = np.zeros((50, 3))
    axes = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    hmap = tr.hand_map(panda, HOME, "panda_joint2", wrist, shoulder, axes)
    np.testing.assert_allclose(hmap(wrist.mean(axis=0)[None])[0], hmap.p_home, atol=1e-15)
    np.testing.assert_allclose(hmap.p_home, tr.hand_position(panda, HOME), atol=1e-15)
    d_h = np.linalg.norm(wrist[1] - wrist[0])
    d_r = np.linalg.norm(hmap(wrist[1:2]) - hmap(wrist[0:1]))
    assert d_r == pytest.approx(hmap.scale * d_h, rel=1e-12)


def test_geodesic_transfer_has_less_energy(panda) -> None:
    """A curved 10 cm hand path: IK reaches it; the geodesic between the ends is cheaper."""
    p0 = tr.hand_position(panda, HOME)
    s = np.linspace(0.0, 1.0, 31)
    targets = p0 + np.column_stack([0.1 * s, 0.05 * np.sin(np.pi * s), -0.05 * s])
    q_kin, err = tr.kinematic_retarget(panda, targets, HOME)
    assert err.max() < 1e-4  # the small pulls on the redundant joints cost < 0.1 mm
    assert np.all(q_kin >= panda.q_min) and np.all(q_kin <= panda.q_max)
    t = s * 1.0
    res = tr.transfer_segment(KineticEnergyMetric(panda), panda, t, targets, q_kin)
    np.testing.assert_allclose(res.q_geodesic[[0, -1]], q_kin[[0, -1]], atol=1e-6)
    assert res.energy_geodesic < res.energy_kinematic
    assert res.hand_dev_kinematic < 1e-4
    assert res.hand_dev_geodesic <= 0.01 or res.pieces == 8
    assert res.hand_dev_geodesic < 0.02
    with pytest.raises(InvalidSynergyInput, match="T >= 3"):
        tr.transfer_segment(KineticEnergyMetric(panda), panda, t[:2], targets[:2], q_kin[:2])


def test_fit_scale_keeps_a_followable_path_and_shrinks_an_unreachable_one(panda) -> None:
    """A 10 cm circle at home is kept at its reach scale; the same circle 40x larger
    (beyond the Panda's reach) is shrunk until the kinematic retargeting reaches it,
    and a tight torque margin shrinks it until holding every posture against gravity
    (RNEA at rest, an independent evaluation) stays inside the margin."""
    s = np.linspace(0.0, 2 * np.pi, 40)
    wrist = np.column_stack([0.05 * np.cos(s), 0.05 * np.sin(s), 0.02 * np.sin(2 * s)])
    shoulder = wrist.mean(axis=0) + [0.0, 0.0, 0.3]
    hmap = tr.hand_map(panda, HOME, "panda_joint2", wrist, np.tile(shoulder, (40, 1)), np.eye(3))
    kept, fit = tr.fit_scale(panda, hmap, wrist, HOME, frames=10)
    assert kept.scale == hmap.scale == fit.reach_scale and fit.trials == 1
    checked = np.linspace(0, len(wrist) - 1, 10).astype(int)  # the frames fit_scale checks
    big = hmap._replace(scale=40 * hmap.scale, reach_scale=40 * hmap.scale)
    kept, fit = tr.fit_scale(panda, big, wrist, HOME, frames=10, reach_tol=0.002)
    assert 0 < kept.scale < big.scale and fit.reach_error_p95 <= 0.002
    _, err = tr.kinematic_retarget(panda, kept(wrist[checked]), HOME)
    assert np.percentile(err, 95) <= 0.002 + 1e-9
    _, err_up = tr.kinematic_retarget(panda, big._replace(scale=1.3 * kept.scale)(wrist), HOME)
    assert err_up.max() > 0.002  # the bisection's bracket: a little larger is not reachable
    # holding the home posture takes 0.253 x tau_max on the Panda's worst joint
    tight, fit = tr.fit_scale(panda, big, wrist, HOME, frames=10, torque_margin=0.3, trials=10)
    assert tight.scale < kept.scale and fit.gravity_ratio <= 0.3
    Q, _ = tr.kinematic_retarget(panda, tight(wrist[checked]), HOME)
    data, zero = panda.model.createData(), np.zeros(panda.nv)
    g = np.array([pin.rnea(panda.model, data, q, zero, zero) for q in Q])
    assert np.max(np.abs(g) / panda.tau_max) <= 0.3 + 1e-9
    with pytest.raises(InvalidSynergyInput, match="at home: 0.25"):
        tr.fit_scale(panda, big, wrist, HOME, frames=10, torque_margin=0.2, trials=3)
    with pytest.raises(InvalidSynergyInput, match="torque_margin"):
        tr.fit_scale(panda, big, wrist, HOME, torque_margin=1.5)
