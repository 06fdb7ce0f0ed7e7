"""Tests of geosyn.synergies.figures: the paper's Figures 1 and 2 as PNGs plus their data."""

from __future__ import annotations

import json
import subprocess
import sys

import matplotlib.image as mpimg
import numpy as np
import pinocchio as pin
import pytest

from conftest import get_metric, get_robot
from geosyn.metrics.geodesic import exp
from geosyn.robots.kinematics import joint_positions
from geosyn.synergies import InvalidSynergyInput, orthonormal_synergies
from geosyn.synergies import InvalidSynergyInput as DimensionMismatch
from geosyn.synergies.figures import (
    PAPER_WEIGHTS,
    figure_configuration_space,
    figure_synergy_combinations,
)

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def check_png(path, width, height):
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE and len(data) > 20_000
    img = mpimg.imread(path)
    assert img.shape[:2] == (height, width)
    assert img[..., :3].std() > 0.05  # not blank


def test_configuration_space_figure(tmp_path):
    metric, robot = get_metric("planar2"), get_robot("planar2")
    q0, q1 = np.array([-1.0, 2.0]), np.array([1.5, -0.5])
    fig = figure_configuration_space(metric, q0, q1, tmp_path / "fig1.png", robot)
    check_png(fig.path, 1950, 690)
    geo, line = fig.geodesic, fig.straight
    np.testing.assert_allclose(geo.q[0], q0, atol=0)
    np.testing.assert_allclose(geo.q[-1], q1, atol=1e-8)
    np.testing.assert_allclose(line.q[[0, -1]], [q0, q1], atol=1e-15)
    # Energy along a unit-duration geodesic is 1/2 v0^T G(q0) v0 (constant speed).
    v0 = geo.v[0]
    np.testing.assert_allclose(fig.energy_geodesic, 0.5 * v0 @ metric.G(q0) @ v0, rtol=1e-3)
    # Straight line: E = 1/2 dq^T (integral of G) dq, here by a fine trapezoid rule.
    dq = q1 - q0
    s = np.linspace(0, 1, 2001)
    vals = np.array([dq @ metric.G(q0 + si * dq) @ dq for si in s])
    e_line = 0.5 * np.sum(0.5 * (vals[1:] + vals[:-1]) * np.diff(s))
    np.testing.assert_allclose(fig.energy_straight, e_line, rtol=1e-5)
    print(
        f"figure 1: geodesic energy {fig.energy_geodesic:.4f} J s, straight line "
        f"{fig.energy_straight:.4f} J s"
    )
    assert fig.energy_geodesic < fig.energy_straight


def test_synergy_combination_figure(tmp_path):
    metric, robot = get_metric("talos_arm"), get_robot("talos_arm")
    q0 = np.array([0.3, 0.4, 0.0, -1.2, 0.0, 0.0, 0.0])
    basis = orthonormal_synergies(metric, q0, 2)
    fig = figure_synergy_combinations(
        metric, robot, q0, basis.synergies, path=tmp_path / "fig2.png"
    )
    check_png(fig.path, 1512, 960)
    assert len(fig.hand_paths) == 2 + len(PAPER_WEIGHTS) == len(fig.labels)
    data = robot.model.createData()
    fid = robot.frame_id(robot.ee_frame)
    V = basis.V
    for j, w in enumerate([(1.0, 0.0), (0.0, 1.0), *PAPER_WEIGHTS]):
        ref = exp(metric, q0, w[0] * V[:, 0] + w[1] * V[:, 1])
        np.testing.assert_allclose(fig.trajectories[j].q, ref.q, atol=1e-12)
        pin.framesForwardKinematics(robot.model, data, ref.q[-1])
        np.testing.assert_allclose(fig.hand_paths[j][-1], data.oMf[fid].translation, atol=1e-12)
        np.testing.assert_allclose(fig.hand_paths[j][0], fig.hand_paths[0][0], atol=1e-12)
    # Skeleton ends at the hand.
    pts = joint_positions(robot, q0, robot.ee_frame)
    np.testing.assert_allclose(pts[-1], fig.hand_paths[0][0], atol=1e-12)


def test_bad_input(tmp_path):
    metric, robot = get_metric("planar2"), get_robot("planar2")
    with pytest.raises(InvalidSynergyInput, match=".png"):
        figure_configuration_space(metric, [0, 1], [1, 0], tmp_path / "fig.jpg", robot)
    with pytest.raises(DimensionMismatch, match="n = 2"):
        figure_configuration_space(get_metric("planar3"), [0] * 3, [1] * 3, tmp_path / "f.png")
    basis = orthonormal_synergies(metric, np.array([0.0, 1.0]), 2)
    with pytest.raises(InvalidSynergyInput, match="exactly 2"):
        figure_synergy_combinations(
            metric, robot, [0.0, 1.0], basis.synergies[:1], path=tmp_path / "f.png"
        )


def test_importing_figures_changes_nothing_global():
    """A fresh interpreter: importing the figures module selects no matplotlib backend."""
    probe = (
        "import json, os\n"
        "import matplotlib\n"
        "before = (dict(os.environ), matplotlib.rcParams._get_backend_or_none())\n"
        "import geosyn.synergies.figures\n"
        "after = (dict(os.environ), matplotlib.rcParams._get_backend_or_none())\n"
        "print(json.dumps([after == before, 'matplotlib.pyplot' in __import__('sys').modules]))\n"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert json.loads(out.stdout.strip().splitlines()[-1]) == [True, False]
