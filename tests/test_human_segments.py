"""Segmentation at hand-speed minima, and the geodesic/line comparison of a segment."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from geosyn.metrics import CoupledMetric, KineticEnergyMetric
from geosyn.metrics.geodesic import exp
from geosyn.synergies.errors import InvalidSynergyInput
from geosyn.synergies.human import segments as sg
from geosyn.synergies.human.errors import DataSourceError
from geosyn.synergies.human.myoarm import load_myoarm


def test_split_at_speed_minima() -> None:
    fps = 30.0
    t = np.arange(0, 6, 1 / fps)
    speed = np.abs(np.sin(np.pi * t))  # minima every 1 s; the recording end closes the last
    hand = np.column_stack([np.cumsum(speed) / fps, np.zeros_like(t), np.zeros_like(t)])
    segs = sg.split(speed, hand, fps, min_duration=0.4, min_travel=0.05)
    assert [(a, b) for a, b in segs] == [
        (0, 30),
        (30, 60),
        (60, 90),
        (90, 120),
        (120, 150),
        (150, 179),
    ]
    # segments shorter in travel than asked are dropped
    assert sg.split(speed, hand * 0.01, fps) == []
    with pytest.raises(InvalidSynergyInput, match="speed"):
        sg.split(speed[:-1], hand, fps)


@pytest.mark.slow  # compiles the arm's geodesic functions once (cached on disk)
def test_a_geodesic_segment_is_its_own_geodesic() -> None:
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            arm = load_myoarm()
    except DataSourceError as err:
        if err.unreachable:
            pytest.skip(f"PyPI unreachable: {err}")
        raise
    robot = arm.robot
    metric = CoupledMetric(KineticEnergyMetric(robot), robot.coupling)
    z0 = np.array([0.3, 0.8, 0.2, 1.0, 0.1, 0.1, 0.0])
    v0 = np.array([0.3, 0.4, -0.3, 0.6, 0.4, 0.1, 0.2])
    z = exp(metric, z0, v0, duration=1.0, steps=60).q  # a geodesic "recording"
    seg = sg.compare_segment(metric, robot, z, "synthetic", 0, len(z) - 1)
    assert seg.geodesic_ok
    assert seg.geodesic_dev < 2e-3  # sampling of the candidate path only
    assert seg.line_dev > 5 * seg.geodesic_dev
    assert seg.geodesic_hand_dev < seg.line_hand_dev
