"""Config sections to library objects (experiments/build.py)."""

from __future__ import annotations

import numpy as np

from geosyn.experiments.build import build_obstacles
from geosyn.experiments.loader import load_config
from geosyn.metrics.shaping import Box


def _config_with(obstacle: str):
    """The built-in obstacle experiment with its obstacles replaced (a --set override)."""
    cfg, _ = load_config("panda_obstacle_shaping", [f"scene.obstacles=[{obstacle}]"])
    return cfg


def test_box_rpy_gives_the_urdf_rotation() -> None:
    """rpy = (0, 0, pi/2): a quarter turn about z, R = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]."""
    cfg = _config_with(
        {
            "type": "box",
            "center": [0.5, 0, 0.3],
            "half_extents": [0.1, 0.2, 0.3],
            "rpy": [0, 0, np.pi / 2],
        }
    )
    (box,) = build_obstacles(cfg)
    assert isinstance(box, Box)
    expected = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(np.asarray(box.rotation), expected, atol=1e-15)


def test_box_without_rpy_is_axis_aligned() -> None:
    cfg = _config_with("{type: box, center: [0.5, 0, 0.3], half_extents: [0.1, 0.2, 0.3]}")
    (box,) = build_obstacles(cfg)
    np.testing.assert_array_equal(np.asarray(box.rotation), np.eye(3))
