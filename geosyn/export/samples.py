"""The built-in reference of an export: a Python reference sampled on a time grid."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from geosyn.controllers import JointTrajectoryReference, Reference
from geosyn.core.validation import check_positive


class ReferenceSamples(NamedTuple):
    """Samples ``(t, q, v, a)`` of a reference; the C library interpolates them like
    ``JointTrajectoryReference(t, q, v, a)`` (quintic Hermite).

    Attributes:
        t: (T,) strictly increasing times [s].
        q: (T, nq) joint positions [rad].
        v: (T, nq) joint velocities [rad/s].
        a: (T, nq) joint accelerations [rad/s^2].
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray

    def reference(self) -> JointTrajectoryReference:
        """The Python reference the C library tracks (allocates)."""
        return JointTrajectoryReference(self.t, self.q, self.v, self.a)


class SamplingError(NamedTuple):
    """Largest difference between a reference and its sampled interpolant, at the
    interval midpoints.

    Attributes:
        q: [rad]. v: [rad/s]. a: [rad/s^2].
    """

    q: float
    v: float
    a: float


def sample_reference(ref: Reference, dt: float) -> ReferenceSamples:
    """Sample ``ref`` over its moving part ``[t0, t0 + duration]`` every ~``dt``.

    Args:
        ref: the reference (any `Reference`).
        dt: largest sample spacing [s], > 0; the grid is uniform and ends exactly at
            ``t0 + duration``.

    Returns:
        ``ceil(duration / dt) + 1`` samples (at least 2).
    """
    dt = check_positive(dt, "sample_dt", unit="s")
    count = max(2, math.ceil(ref.duration / dt - 1e-9) + 1)
    t = ref.t0 + np.linspace(0.0, ref.duration, count)
    rows = [ref.sample(float(tk)) for tk in t]
    q, v, a = (np.array([r[i] for r in rows], dtype=np.float64) for i in range(3))
    return ReferenceSamples(t, q, v, a)


def sampling_error(ref: Reference, samples: ReferenceSamples) -> SamplingError:
    """`SamplingError` of ``samples`` against ``ref`` (one sample per interval midpoint)."""
    interp = samples.reference()
    mids = 0.5 * (samples.t[1:] + samples.t[:-1])
    err = np.zeros(3)
    for tm in mids:
        exact, approx = ref.sample(float(tm)), interp.sample(float(tm))
        for i in range(3):
            err[i] = max(err[i], float(np.max(np.abs(exact[i] - approx[i]))))
    return SamplingError(*(float(x) for x in err))
