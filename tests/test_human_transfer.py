"""Transfer of a hand path to the Panda: kinematic retargeting vs the geodesic between its ends."""

from __future__ import annotations

import warnings

import numpy as np
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
