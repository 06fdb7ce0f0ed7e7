"""Fuzz: robot files with seeded hostile numbers (issue 23).

A valid one-link-plus-wrist URDF and MJCF are mutated in one field (mass, an inertia
entry, an axis, a limit, an origin, an include) to a value from a catalogue (NaN, inf,
1e300, negative, zero, text, hex, empty). Loading each must either raise a `GeosynError`
naming the file's part, or give a robot that means something: finite limits in order,
M(q) finite and symmetric positive definite at seeded configurations, and for MJCF,
geosyn's M equal to MuJoCo's own compile of the same file. 0 tracebacks, 0 wrong
exception types, 0 silent NaN, 0 accepted nonsense.
"""

from __future__ import annotations

import random
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from fuzzing import assert_geosyn_error, call_api

from geosyn.robots import Robot, load_robot

CASES = 48
BAD = ["nan", "inf", "-inf", "1e300", "-1e300", "-1", "0", "abc", "", "1e400", "0x10", "1e-300"]

URDF = """<?xml version="1.0"?>
<robot name="fuzz">
  <link name="base"/>
  <link name="upper">
    <inertial><origin xyz="0 0 {com}"/><mass value="{mass}"/>
      <inertia ixx="{ixx}" iyy="0.01" izz="0.001" ixy="{ixy}" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="hand">
    <inertial><origin xyz="0 0 -0.05"/><mass value="0.5"/>
      <inertia ixx="0.001" iyy="0.001" izz="0.0005" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <origin xyz="0 0 {height}"/><axis xyz="{axis}"/>
    <limit lower="{lower}" upper="{upper}" effort="10" velocity="2"/></joint>
  <joint name="wrist" type="revolute"><parent link="upper"/><child link="hand"/>
    <origin xyz="0 0 -0.4"/><axis xyz="1 0 0"/>
    <limit lower="-2" upper="2" effort="5" velocity="2"/></joint>
</robot>
"""
URDF_FIELDS = {
    "mass": "1",
    "ixx": "0.01",
    "ixy": "0",
    "com": "-0.2",
    "height": "0.5",
    "axis": "0 1 0",
    "lower": "-1",
    "upper": "1",
}

MJCF = """<mujoco model="fuzz">
  {include}
  <worldbody>
    <body name="upper" pos="0 0 {height}">
      <joint name="shoulder" type="hinge" axis="{axis}" range="{lower} {upper}" limited="true"/>
      <inertial pos="0 0 {com}" mass="{mass}" diaginertia="{ixx} 0.01 0.001"/>
      <body name="hand" pos="0 0 -0.4">
        <joint name="wrist" type="hinge" axis="1 0 0" range="-2 2" limited="true"/>
        <inertial pos="0 0 -0.05" mass="0.5" diaginertia="0.001 0.001 0.0005"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""
MJCF_FIELDS = {
    "mass": "1",
    "ixx": "0.01",
    "com": "-0.2",
    "height": "0.5",
    "axis": "0 1 0",
    "lower": "-1",
    "upper": "1",
    "include": "",
}
BAD_INCLUDES = [
    '<include file="../../../../../../../../../etc/hostname"/>',
    '<include file="/dev/zero"/>',
    '<include file="/proc/self/environ"/>',
    '<include file="missing.xml"/>',
    '<include file="."/>',
]


def _mutated(kind: str, rng: random.Random) -> tuple[str, str, str]:
    """(file text, field, value) with one field set to a hostile value."""
    fields = dict(URDF_FIELDS if kind == "urdf" else MJCF_FIELDS)
    field = rng.choice(sorted(fields))
    if field == "include":
        value = rng.choice(BAD_INCLUDES)
    elif field == "axis":
        value = rng.choice(["0 0 0", "nan 1 0", "inf 0 0", "1e300 0 0", "0 1", "a b c"])
    else:
        value = rng.choice(BAD)
    fields[field] = value
    return (URDF if kind == "urdf" else MJCF).format(**fields), field, value


def _assert_meaningful(robot: Robot, path: Path, kind: str, rng: random.Random) -> None:
    """An accepted robot: ordered limits, M(q) finite and SPD, MJCF equal to MuJoCo's M."""
    assert np.all(robot.q_min <= robot.q_max)
    model = robot.model
    mj = mujoco.MjModel.from_xml_path(str(path)) if kind == "mjcf" else None
    for _ in range(3):
        q = rng.uniform(-1.0, 1.0) * np.ones(model.nq)
        M = pin.crba(model, model.createData(), q)
        M = np.triu(M) + np.triu(M, 1).T
        assert np.all(np.isfinite(M)), M
        assert np.linalg.eigvalsh(M)[0] > 0.0, M
        if mj is not None:
            d = mujoco.MjData(mj)
            d.qpos[:] = q
            mujoco.mj_forward(mj, d)
            Mmj = np.zeros((mj.nv, mj.nv))
            mujoco.mj_fullM(mj, d, Mmj)
            np.testing.assert_allclose(M, Mmj, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("case", range(CASES))
def test_hostile_robot_file_is_refused_or_meaningful(tmp_path: Path, case: int, capfd) -> None:
    rng = random.Random(2323 + case)
    kind = "urdf" if case % 2 == 0 else "mjcf"
    text, field, value = _mutated(kind, rng)
    folder = tmp_path / "a" / "b" / "c" / "robot"
    folder.mkdir(parents=True)
    path = folder / f"fuzz.{'urdf' if kind == 'urdf' else 'xml'}"
    path.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # e.g. no velocity limit in an MJCF: warned, fine
        result = call_api(load_robot, path)
    what = f"{kind} {field}={value!r}"
    if isinstance(result, Robot):
        _assert_meaningful(result, path, kind, rng)
    else:
        assert_geosyn_error(result, what)
        assert "Traceback" not in str(result)
    capfd.readouterr()  # third-party stderr lines are the CLI's business (issue 23, other part)
