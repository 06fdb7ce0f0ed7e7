"""The study's figures are written as PNG images of the expected size."""

from __future__ import annotations

import numpy as np
from matplotlib.image import imread

from geosyn.synergies.human import figures as fg


def test_figures_are_png(tmp_path) -> None:
    rng = np.random.default_rng(5)
    paths = [
        fg.ik_residuals(rng.uniform(0, 0.02, (100, 3)), ["RightArm", "RightHand", "RightHandIndex1"],
                        tmp_path / "ik.png"),
        fg.segment_fit(rng.uniform(0.01, 0.1, 20), rng.uniform(0.01, 0.1, 20), tmp_path / "s.png"),
        fg.pga_vs_pca([{"k": k, "pga_metric": 1 / k, "pca_metric": 2 / k, "pga_plain": 1.0,
                        "pca_plain": 0.5} for k in (1, 2, 3)], tmp_path / "p.png"),
        fg.hand_paths(*(rng.normal(size=(10, 3)) for _ in range(3)), tmp_path / "h.png", "t"),
    ]  # fmt: skip
    for p in paths:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        image = imread(p)
        assert image.shape[0] > 300 and image.shape[1] > 500
        assert np.ptp(image[..., :3]) > 0.5  # something is drawn
