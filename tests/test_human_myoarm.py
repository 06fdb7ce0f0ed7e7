"""The MyoArm (myo-sim wheel) as a geosyn robot, checked against MuJoCo's compile of the file.

The wheels are fetched with pip into the data cache (GEOSYN_CACHE_DIR); the tests skip
only when PyPI cannot be reached.
"""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

from geosyn.synergies.human.data import MYO_SIM, data_dir, extract
from geosyn.synergies.human.errors import DataSourceError
from geosyn.synergies.human.myoarm import (
    ARM_COORDINATES,
    GIRDLE_JOINTS,
    load_myoarm,
    myoarm_xml,
)


@pytest.fixture(scope="module")
def arm():
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return load_myoarm()
    except DataSourceError as err:
        if err.unreachable:
            pytest.skip(f"PyPI unreachable, cannot fetch {err.package}: {err}")
        raise


def test_provenance_and_licence(arm) -> None:
    root, prov = extract(MYO_SIM, lambda n: False)
    assert prov.version == "0.2.4" and "Apache" in prov.licence
    assert prov.licence_file is not None
    assert "Apache License" in (root / prov.licence_file).read_text()
    import hashlib

    wheel = data_dir() / "wheels" / MYO_SIM.filename
    assert hashlib.sha256(wheel.read_bytes()).hexdigest() == MYO_SIM.sha256


def test_structure_and_muscles(arm) -> None:
    path, _ = myoarm_xml()
    m = mujoco.MjModel.from_xml_path(str(path))
    assert (m.nq, m.nu, m.neq) == (38, 63, 11)  # the file as published
    robot = arm.robot
    assert robot.joint_names == (*GIRDLE_JOINTS[:-1], *ARM_COORDINATES[:2], GIRDLE_JOINTS[-1],
                                 *ARM_COORDINATES[2:])  # fmt: skip
    assert robot.coupling.independent == ARM_COORDINATES
    assert len(arm.muscles) == 63
    assert {a.name for a in arm.muscles} == {
        mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a) for a in range(m.nu)
    }
    f_max = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a): m.actuator_gainprm[a, 2]
             for a in range(m.nu)}  # fmt: skip
    assert all(mu.f_max == f_max[mu.name] > 0 for mu in arm.muscles)
    assert all(s.startswith("muscles:") for s in robot.tau_max_source)
    assert "does not model the muscles" in arm.modelling


def test_mass_matrix_matches_mujoco(arm) -> None:
    """M(q) of the kept joints equals MuJoCo's qM of the published file (fingers at qpos0)."""
    path, _ = myoarm_xml()
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(m.njnt)]
    idx = [names.index(n) for n in arm.robot.joint_names]
    rng = np.random.default_rng(3)
    robot = arm.robot
    from geosyn.metrics import KineticEnergyMetric

    metric = KineticEnergyMetric(robot)
    for _ in range(3):
        q = rng.uniform(np.maximum(robot.q_min, -2), np.minimum(robot.q_max, 2))
        d.qpos[:] = m.qpos0
        d.qpos[idx] = q
        mujoco.mj_forward(m, d)
        M = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M)
        np.testing.assert_allclose(metric.G(q), M[np.ix_(idx, idx)], rtol=1e-9, atol=1e-12)


def test_coupling_satisfies_the_file_equalities(arm) -> None:
    path, _ = myoarm_xml()
    m = mujoco.MjModel.from_xml_path(str(path))
    names = list(arm.robot.joint_names)
    rng = np.random.default_rng(4)
    z = rng.uniform(-0.5, 0.5, arm.robot.coupling.nz)
    q = arm.robot.coupling.q(z)
    for e in range(m.neq):
        j1, j2 = (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, int(i))
                  for i in (m.eq_obj1id[e], m.eq_obj2id[e]))  # fmt: skip
        a0, a1 = m.eq_data[e, :2]
        q1_0, q2_0 = (m.qpos0[m.jnt_qposadr[int(i)]] for i in (m.eq_obj1id[e], m.eq_obj2id[e]))
        lhs = q[names.index(j1)] - q1_0
        assert lhs == pytest.approx(a0 + a1 * (q[names.index(j2)] - q2_0), abs=1e-12)


def test_scaling_sets_segment_lengths(arm) -> None:
    from geosyn.synergies.human.mocap_ik import model_segment_lengths

    base = model_segment_lengths(arm.robot)
    factors = {"shoulder": 0.8, "upper_arm": 1.1, "forearm": 0.95, "hand": 1.2}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scaled = load_myoarm(scale=factors)
    got = model_segment_lengths(scaled.robot)
    for seg, f in factors.items():
        assert got[seg] == pytest.approx(f * base[seg], rel=1e-9)
    assert scaled.robot.model.inertias[5].mass == pytest.approx(arm.robot.model.inertias[5].mass)


def test_with_fingers_27_independent_coordinates(arm) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        hand = load_myoarm(fingers=True)
    assert (hand.robot.nq, hand.robot.coupling.nz) == (38, 27)
    assert len(hand.robot.coupling.constraints) == 11
