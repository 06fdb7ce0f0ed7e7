"""Weight profiles w(d) and velocity gates of the obstacle metric term, as registries.

`geosyn.metrics.shaping.obstacle.ObstacleTerm` selects one of each by name. A profile takes
the clearance, the gain and the cutoff (symbols: parameters of the compiled functions) and
the term for its other settings (d_min, length, epsilon); a gate takes the term for
gate_speed.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import casadi as ca

if TYPE_CHECKING:
    from geosyn.metrics.shaping.obstacle import ObstacleTerm

__all__ = ["GATES", "PROFILES"]


def _inverse_square(d: ca.SX, gain: ca.SX, cutoff: ca.SX, term: ObstacleTerm) -> ca.SX:
    # w = gain (1/d - 1/d_cut)^2 for d < d_cut, 0 beyond: ~gain/d^2 near contact, C1 at the
    # cutoff; d clamped at d_min so the weight stays finite at and inside the boundary.
    dd = ca.fmax(d, term.d_min)
    u = ca.fmax(1.0 / dd - 1.0 / cutoff, 0.0)
    return gain * u * u


def _rmp(d: ca.SX, gain: ca.SX, cutoff: ca.SX, term: ObstacleTerm) -> ca.SX:
    # RMPflow-like bounded weight gain exp(-d/l) / (d/l + eps), times a C1 cutoff factor.
    dd = ca.fmax(d, 0.0)
    s = ca.fmax(1.0 - dd / cutoff, 0.0)
    return gain * s * s * ca.exp(-dd / term.length) / (dd / term.length + term.epsilon)


PROFILES: dict[str, Callable[[ca.SX, ca.SX, ca.SX, ObstacleTerm], ca.SX]] = {
    "inverse_square": _inverse_square,
    "rmp": _rmp,
}
"""Registry of weight profiles ``w(d)`` by name (see `ObstacleTerm`)."""


def _gate_none(ddot: ca.SX, term: ObstacleTerm) -> ca.SX | float:
    return 1.0


def _gate_approach(ddot: ca.SX, term: ObstacleTerm) -> ca.SX:
    # Smoothstep from 0 (d not decreasing) to 1 (approaching at gate_speed or faster).
    s = ca.fmin(ca.fmax(-ddot / term.gate_speed, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


GATES: dict[str, Callable[[ca.SX, ObstacleTerm], ca.SX | float]] = {
    "none": _gate_none,
    "approach": _gate_approach,
}
"""Registry of velocity gates by name (see `ObstacleTerm`)."""
