"""Point-to-point segments of a recorded arm motion, compared with geodesics and lines.

A segment runs between two consecutive minima of the hand (wrist keypoint) speed; it is
kept when it lasts at least ``min_duration`` and the hand moves at least ``min_travel``
between its ends. Each segment's joint path is compared with two candidates between the
same end configurations: the geodesic of the arm's metric (log map by shooting, then
exp) and the straight line in the independent coordinates z. The comparison is purely
geometric (time law ignored): the mean, over the segment's samples, of the distance to
the closest point of the candidate path, in z [rad] and for the hand [m].
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from geosyn.core.errors import GeosynError
from geosyn.metrics.base import Metric
from geosyn.metrics.geodesic import exp, log
from geosyn.robots import Robot
from geosyn.synergies.errors import InvalidSynergyInput
from geosyn.synergies.human.mocap_ik import coupling_of, model_keypoints


class Segment(NamedTuple):
    """One point-to-point segment and its fit by a geodesic and by a straight line."""

    sequence: str
    start: int  # first frame
    stop: int  # last frame (inclusive)
    travel: float  # hand displacement between the ends [m]
    geodesic_dev: float  # mean closest-point distance in z to the geodesic [rad]
    line_dev: float  # ... to the straight line in z [rad]
    geodesic_hand_dev: float  # mean closest-point distance of the hand paths [m]
    line_hand_dev: float  # [m]
    geodesic_ok: bool  # the log map converged


def hand_speed(robot: Robot, z: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Hand positions (T, 3) [m] and speed (T,) [m/s] of a joint trajectory z (T, nz)."""
    coupling = coupling_of(robot)
    hand = np.array([model_keypoints(robot, coupling.q(zz), ("RightHand",))[0] for zz in z])
    return hand, np.linalg.norm(np.gradient(hand, 1.0 / fps, axis=0), axis=1)


def split(
    speed: np.ndarray,
    hand: np.ndarray,
    fps: float,
    *,
    min_duration: float = 0.4,
    min_travel: float = 0.05,
) -> list[tuple[int, int]]:
    """Segments between consecutive speed minima (see the module doc).

    Args:
        speed: (T,) hand speed [m/s].
        hand: (T, 3) hand positions [m].
        fps: frame rate [Hz].
        min_duration: shortest segment kept [s].
        min_travel: smallest hand displacement between the ends kept [m].

    Returns:
        ``(start, stop)`` frame pairs (inclusive).
    """
    if speed.ndim != 1 or len(speed) != len(hand):
        raise InvalidSynergyInput(f"speed must be (T,) like hand, got {speed.shape}", "speed")
    from scipy.signal import find_peaks  # heavy (scipy.stats): imported where used

    minima, _ = find_peaks(-speed, distance=max(1, int(min_duration * fps / 2)))
    cuts = [0, *minima.tolist(), len(speed) - 1]
    out = []
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        if (b - a) / fps >= min_duration and np.linalg.norm(hand[b] - hand[a]) >= min_travel:
            out.append((a, b))
    return out


def _closest_mean(path: np.ndarray, candidate: np.ndarray) -> float:
    """Mean over path samples of the distance to the closest candidate sample."""
    d = np.linalg.norm(path[:, None, :] - candidate[None, :, :], axis=2)
    return float(d.min(axis=1).mean())


def compare_segment(
    metric: Metric,
    robot: Robot,
    z: np.ndarray,
    name: str,
    start: int,
    stop: int,
    *,
    samples: int = 100,
) -> Segment:
    """One segment against the geodesic and the straight line between its ends.

    Args:
        metric: the arm's metric on z (e.g. `CoupledMetric` of the arm).
        robot: the arm.
        z: (T, nz) joint trajectory [rad].
        name: sequence name.
        start, stop: frames (inclusive).
        samples: points on each candidate path.
    """
    coupling = coupling_of(robot)
    path = z[start : stop + 1]
    za, zb = path[0], path[-1]
    ok = True
    try:
        v = log(metric, za, zb, v_init=zb - za, steps=samples)
        geo = exp(metric, za, v, duration=1.0, steps=samples).q
    except GeosynError:  # a failed shooting is reported (geodesic_ok), the segment kept
        ok = False
        geo = np.linspace(za, zb, samples + 1)
    line = np.linspace(za, zb, samples + 1)

    def hand(Z: np.ndarray) -> np.ndarray:
        return np.array([model_keypoints(robot, coupling.q(zz), ("RightHand",))[0] for zz in Z])

    h_path, h_geo, h_line = hand(path), hand(geo), hand(line)
    return Segment(
        name,
        start,
        stop,
        float(np.linalg.norm(h_path[-1] - h_path[0])),
        _closest_mean(path, geo),
        _closest_mean(path, line),
        _closest_mean(h_path, h_geo),
        _closest_mean(h_path, h_line),
        ok,
    )
