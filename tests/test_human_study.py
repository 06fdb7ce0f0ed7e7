"""The study's human frame: forward, left, up of the MyoArm, and its mirror for left arms."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from geosyn.synergies.human import mocap_ik as ik
from geosyn.synergies.human import study as st
from geosyn.synergies.human.errors import DataSourceError
from geosyn.synergies.human.myoarm import load_myoarm


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


def test_human_axes_and_their_mirror(arm) -> None:
    """Forward is where the forearm points with the elbow at 90 degrees (horizontal), up
    is +z; the mirror flips only 'left', so a right arm's reach to its right becomes a
    left arm's reach to its left."""
    A = st.human_axes(arm)
    M = st.human_axes(arm, mirror=True)
    np.testing.assert_allclose(A.T @ A, np.eye(3), atol=1e-12)
    assert np.linalg.det(A) == pytest.approx(1.0, abs=1e-12)
    assert np.linalg.det(M) == pytest.approx(-1.0, abs=1e-12)
    np.testing.assert_allclose(M[:, [0, 2]], A[:, [0, 2]], atol=1e-15)
    np.testing.assert_allclose(M[:, 1], -A[:, 1], atol=1e-15)
    np.testing.assert_allclose(A[:, 2], [0.0, 0.0, 1.0], atol=1e-15)
    robot = arm.robot
    lo, hi = ik.z_box(robot)
    z = np.clip(np.zeros(len(lo)), lo, hi)
    z[robot.coupling.independent.index("elbow_flexion_r")] = np.pi / 2
    elbow, wrist = ik.model_keypoints(robot, robot.coupling.q(z), ("RightForeArm", "RightHand"))
    forearm = (wrist - elbow) * [1.0, 1.0, 0.0]
    assert forearm @ A[:, 0] == pytest.approx(np.linalg.norm(forearm), rel=1e-12)
    # the right shoulder lies to the right of the chest: its 'left' coordinate relative
    # to the sternum is negative in the unmirrored frame
    sternum, shoulder = ik.model_keypoints(
        robot, robot.coupling.q(z), ("RightShoulder", "RightArm")
    )
    assert (shoulder - sternum) @ A[:, 1] < 0 < (shoulder - sternum) @ M[:, 1]
