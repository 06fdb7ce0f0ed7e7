"""Parallel transport on a stance (geosyn.metrics.stance_transport).

References: invariants of the Levi-Civita connection of the induced metric: transported
inner products are conserved (the Gram matrix, falling as dt^4), a geodesic's velocity is
its own transport, transported vectors stay tangent; and the bracket term is needed (with
its sign flipped the Gram matrix drifts by O(1)).
"""

from __future__ import annotations

import numpy as np
import pytest
from floating_cases import load_quietly

import geosyn.metrics.stance_transport as transport_module
from geosyn.metrics import FloatingKineticEnergyMetric
from geosyn.metrics.errors import StanceError
from geosyn.metrics.stance import Stance
from geosyn.metrics.stance_transport import transport_along_geodesic


def start(name: str) -> tuple[Stance, np.ndarray, np.ndarray, np.ndarray]:
    """A stance, a tangent start (q0, v0) and three tangent vectors (the last one v0)."""
    robot = load_quietly(name)
    metric = FloatingKineticEnergyMetric(robot)
    q = robot.neutral()
    rng = np.random.default_rng(26)
    if name == "go2":
        q[7:] = np.tile([0.0, 0.8, -1.6], 4)
        stance = Stance(metric, ["FL_foot", "FR_foot", "RL_foot", "RR_foot"], q, points=True)
    else:
        q[2] = 1.0
        q[7:] += rng.uniform(-0.2, 0.2, robot.nq - 7)
        stance = Stance(metric, ["left_sole_link", "right_sole_link"], q)
    scale = 0.1 if name == "go2" else 0.3  # go2: far from straight legs
    q0, v0 = stance.project(q, rng.normal(scale=scale, size=robot.nv))
    W = np.array([stance.project(q0, rng.normal(size=robot.nv))[1] for _ in range(2)] + [v0])
    return stance, q0, v0, W


def gram_drift(stance: Stance, tr) -> float:  # type: ignore[no-untyped-def]
    G = np.array([w @ stance.metric.G(q) @ w.T for q, w in zip(tr.q, tr.w, strict=True)])
    return float(np.abs(G - G[0]).max() / np.abs(G[0]).max())


# measured drifts: TALOS 2.6e-5 / 1.6e-6 (50 / 100 steps), go2 2.4e-4 / 1.4e-5 (100 / 200
# steps: its light legs fold fast, |v| up to 14): the integration error, falling as dt^4
@pytest.mark.parametrize(
    ("name", "steps", "tol"), [("talos_reduced", 50, 5e-6), ("go2", 100, 5e-5)]
)
def test_inner_products_are_conserved_and_the_velocity_is_its_own_transport(
    name, steps, tol
) -> None:
    stance, q0, v0, W = start(name)
    coarse = transport_along_geodesic(stance, q0, v0, W, duration=1.0, steps=steps)
    fine = transport_along_geodesic(stance, q0, v0, W, duration=1.0, steps=2 * steps)
    drift = gram_drift(stance, coarse), gram_drift(stance, fine)
    assert drift[1] < tol and drift[0] / drift[1] > 12.0
    assert np.abs(fine.w[:, 2] - fine.v).max() < 1e-10 * np.abs(fine.v).max()
    assert (
        max(np.abs(stance.jacobian(q) @ w.T).max() for q, w in zip(fine.q, fine.w, strict=True))
        < 1e-10
    )
    assert np.abs(fine.w[-1, :2] - W[:2]).max() > 0.05 * np.abs(W[:2]).max()  # they turned


def test_the_bracket_term_is_needed(monkeypatch) -> None:
    stance, q0, v0, W = start("talos_reduced")
    right = gram_drift(stance, transport_along_geodesic(stance, q0, v0, W, steps=50))
    true_connection = transport_module.connection

    def flipped(stance_, q, v, w):  # type: ignore[no-untyped-def]
        out = true_connection(stance_, q, v, w)
        out[:6] -= (
            transport_module.pin.Motion(v[:6]).cross(transport_module.pin.Motion(w[:6])).vector
        )
        return out

    monkeypatch.setattr(transport_module, "connection", flipped)
    wrong = gram_drift(stance, transport_along_geodesic(stance, q0, v0, W, steps=50))
    assert right < 1e-4 and wrong > 1e-2  # measured 2.6e-5 and 0.31


def test_vectors_off_the_stance_are_refused() -> None:
    stance, q0, v0, W = start("talos_reduced")
    with pytest.raises(StanceError, match="held-frame velocity"):
        transport_along_geodesic(stance, q0, v0, W[0] + 0.1)
    with pytest.raises(StanceError, match=r"shape \(nv,\) or \(m, nv\)"):
        transport_along_geodesic(stance, q0, v0, W[:, :5])
