"""A fitted map from target positions to synergy weights, refined when it misses.

For synergies combined at a fixed start ``q_s`` over a fixed duration, the hand's final
position is a smooth function ``p(w)`` of the weights (`geosyn.synergies.reach`).
`SynergyMap.fit` samples seeded weights, integrates each combination once (every sample
``(p(w), w)`` is the exact `reach` solution of its own target), and fits the inverse
``w = f(p)`` by a polynomial least-squares regression in the normalised position. At run
time `SynergyMap.weights` costs one small matrix product; `SynergyMap.solve` checks the
guess with one geodesic integration and, when the hand misses the target by more than a
bound, refines the weights on ``|p(w) - p*|^2`` (`reach`'s objective) from the guess:
quasi-Newton steps ``dw = -(df/dp) r`` with the map's own derivative (one integration
each), then, if those stall, Gauss-Newton with a forward-difference Jacobian (m + 1
integrations per iteration).
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import combinations_with_replacement
from typing import NamedTuple

import numpy as np

from geosyn.core.types import Matrix, Vector
from geosyn.core.validation import check_int, check_positive
from geosyn.metrics.geodesic import Geodesic, exp
from geosyn.metrics.geodesic.shooting import Shooter
from geosyn.robots.kinematics import frame_position
from geosyn.robots.robot import Robot
from geosyn.synergies.errors import InvalidSynergyInput, synergy_input
from geosyn.synergies.synergy import (
    GeodesicSynergy,
    _check_synergies,
    as_vector,
    check_robot,
    transported_velocities,
)


class MapSolution(NamedTuple):
    """Weights for a target.

    Attributes:
        weights: (m,) synergy weights [-].
        map_error: distance of the hand from the target with the map's weights [m].
        error: distance after refinement (= ``map_error`` when not refined) [m].
        refined: whether refinement ran.
        iterations: refinement iterations.
        trajectory: the combined geodesic of ``weights`` over the map's duration.
    """

    weights: Vector
    map_error: float
    error: float
    refined: bool
    iterations: int
    trajectory: Geodesic


def monomials(x: Matrix, degree: int) -> Matrix:
    """(N, F) all monomials of the columns of ``x`` (N, d) up to ``degree``, 1 first."""
    cols = [np.ones(len(x))]
    for k in range(1, degree + 1):
        for idx in combinations_with_replacement(range(x.shape[1]), k):
            cols.append(np.prod(x[:, list(idx)], axis=1))
    return np.column_stack(cols)


class SynergyMap:
    """Target position -> synergy weights, for synergies combined at ``q_start``.

    Build, then `fit` once (allocates the samples); `weights` and `solve` are per call.

    Args:
        synergies: m synergies sharing one metric.
        frame: the frame brought to the target.
        robot: the robot.
        q_start: (n,) start [rad]; the first synergy's base by default.
        duration: motion duration [s].
        steps: RK4 steps of each geodesic (the same in fitting and use).
        degree: polynomial degree of the regression, 1..4.

    Attributes:
        V: (n, m) synergy velocities transported to ``q_start`` [rad/s].
    """

    def __init__(
        self,
        synergies: Sequence[GeodesicSynergy],
        frame: str,
        robot: Robot,
        q_start: Vector | None = None,
        duration: float = 1.0,
        steps: int = 50,
        degree: int = 3,
    ) -> None:
        syns = _check_synergies(synergies)
        self.metric = syns[0].metric
        self.robot = check_robot(robot, self.metric.n)
        self.frame_id = robot.frame_id(frame)
        with synergy_input("duration"):
            self.duration = check_positive(duration, "duration", "s")
        with synergy_input("steps"):
            self.steps = check_int(steps, "steps", low=4)
        with synergy_input("degree"):
            self.degree = check_int(degree, "degree", low=1, high=4)
        self.q_start = (
            syns[0].q0.copy() if q_start is None else as_vector(q_start, self.metric.n, "q_start")
        )
        self.V = transported_velocities(syns, self.q_start, steps=self.steps)
        self.m = self.V.shape[1]
        self._data = robot.model.createData()
        # q(T) of exp(q_s, T v) equals q(1) of exp(q_s, v T): unit-time shooting
        self._shooter = Shooter(self.metric, self.q_start, self.steps)
        self.coef: Matrix | None = None
        self._center = np.zeros(3)
        self._scale = np.ones(3)

    # -- the forward map ------------------------------------------------------------
    def endpoint(self, w: Vector) -> Vector:
        """(3,) frame position [m] at the end of the motion with weights ``w`` (one
        geodesic integration)."""
        q = self._shooter.end(self.duration * (self.V @ np.asarray(w, dtype=np.float64)))
        return frame_position(self.robot, q, self.frame_id, self._data)

    def trajectory(self, w: Vector) -> Geodesic:
        """The combined geodesic of weights ``w`` over ``duration`` (allocates)."""
        return exp(self.metric, self.q_start, self.V @ np.asarray(w), self.duration, self.steps)

    # -- fitting -------------------------------------------------------------------
    def sample(self, n: int, weight_scale: float, seed: int) -> tuple[Matrix, Matrix]:
        """``n`` seeded weights (uniform in ``[-weight_scale, weight_scale]^m``) and their
        endpoints: ((n, 3) positions [m], (n, m) weights)."""
        rng = np.random.default_rng(seed)
        W = rng.uniform(-weight_scale, weight_scale, size=(n, self.m))
        return np.array([self.endpoint(w) for w in W]), W

    def fit(
        self, n_samples: int = 400, weight_scale: float = 0.5, seed: int = 0, ridge: float = 1e-9
    ) -> SynergyMap:
        """Fit the regression on ``n_samples`` seeded samples (returns self).

        Raises:
            InvalidSynergyInput: fewer samples than regression features.
        """
        P, W = self.sample(check_int(n_samples, "n_samples", low=1), weight_scale, seed)
        self._center = P.mean(axis=0)
        self._scale = np.maximum(P.std(axis=0), 1e-9)
        X = monomials((P - self._center) / self._scale, self.degree)
        if X.shape[0] < X.shape[1]:
            raise InvalidSynergyInput(
                f"n_samples must be >= {X.shape[1]} for degree {self.degree}", "n_samples"
            )
        A = X.T @ X + ridge * np.eye(X.shape[1])
        self.coef = np.linalg.solve(A, X.T @ W)
        return self

    def weights(self, target: Vector) -> Vector:
        """(m,) the map's weights for a target position (3,) [m]."""
        if self.coef is None:
            raise InvalidSynergyInput("the map is not fitted: call fit() first", "map")
        x = (np.asarray(target, dtype=np.float64) - self._center) / self._scale
        return (monomials(x[None, :], self.degree) @ self.coef)[0]

    def map_jacobian(self, target: Vector, h: float = 1e-5) -> Matrix:
        """(m, 3) derivative of `weights` at ``target`` [1/m] (central differences)."""
        p = np.asarray(target, dtype=np.float64)
        cols = [(self.weights(p + h * e) - self.weights(p - h * e)) / (2 * h) for e in np.eye(3)]
        return np.column_stack(cols)

    # -- use -----------------------------------------------------------------------
    def solve(
        self,
        target: Vector,
        bound: float = 5e-3,
        tol: float = 1e-4,
        max_iter: int = 8,
        prior: tuple[Vector, Vector] | None = None,
    ) -> MapSolution:
        """The map's weights for ``target``, refined when they miss it by more than ``bound``.

        Args:
            target: (3,) target position [m].
            bound: refine when the map's hand error exceeds this [m].
            tol: refinement stops below this error [m].
            max_iter: Gauss-Newton iterations at most.
            prior: (target (3,) [m], its solved weights (m,)) of a nearby earlier solve
                (a re-plan): the guess is those weights moved by the map's difference,
                ``w_prev + f(p) - f(p_prev)``, which keeps the earlier refinement.
        """
        p_star = as_vector(target, 3, "target")
        w = self.weights(p_star)
        if prior is not None:
            w = np.asarray(prior[1], dtype=np.float64) + w - self.weights(prior[0])
        geo = self.trajectory(w)  # its end checks the guess: no separate integration
        r = frame_position(self.robot, geo.q[-1], self.frame_id, self._data) - p_star
        err0 = err = float(np.linalg.norm(r))
        it = 0
        if err0 > bound:
            # quasi-Newton: dw = (df/dp) dp with the map's own derivative (one
            # integration per iteration); Gauss-Newton with a forward-difference
            # Jacobian (m + 1 integrations) when that stops decreasing the error
            F = self.map_jacobian(p_star)
            while it < max_iter and err > tol:
                w_new = w - F @ r
                r_new = self.endpoint(w_new) - p_star
                it += 1
                if float(np.linalg.norm(r_new)) >= err:
                    break
                w, r, err = w_new, r_new, float(np.linalg.norm(r_new))
            h = 1e-6
            while it < max_iter and err > tol:
                J = np.column_stack(
                    [(self.endpoint(w + h * e) - p_star - r) / h for e in np.eye(self.m)]
                )
                w = w + np.linalg.lstsq(J, -r, rcond=None)[0]
                r = self.endpoint(w) - p_star
                err = float(np.linalg.norm(r))
                it += 1
            geo = self.trajectory(w)
        return MapSolution(w, err0, err, err0 > bound, it, geo)


__all__ = ["MapSolution", "SynergyMap", "monomials"]
