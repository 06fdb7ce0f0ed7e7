"""Crocoddyl's side of ``benchmarks/mpc_vs_crocoddyl.py``: a torque-level tracking MPC.

Runs in the Crocoddyl venv (``bash benchmarks/setup_crocoddyl.sh`` makes ``.venv-croc``;
it needs only crocoddyl, pinocchio and numpy, never geosyn)::

    .venv-croc/bin/python benchmarks/croc_runner.py --reference REF.npz --out OUT.npz \
        [--horizon 10 40] [--scenario on_reference offset_at_rest] [--model-check M.npz] \
        [--threads 1]

The OCP, Crocoddyl's usual way: full state ``x = (q, v)``, torque controls, one
``IntegratedActionModelRK`` (RK4, one step of ``MPC_DT`` = 20 ms) per running node on
``DifferentialActionModelFreeFwdDynamics`` (``pin.aba`` with armature and gravity), torque
limits as control bounds, solved by ``SolverBoxFDDP``. Costs, the same weights as
geosyn's ``GeodesicMPC`` defaults:

- running node k: ``|q - q_r|^2_{W_q} + |v - v_r|^2_{W_v} + w_tau |tau - tau_r|^2``, with
  ``(q_r, v_r, a_r)`` the reference at the node's *midpoint* ``t + (k + 1/2) dt`` and
  ``tau_r = RNEA(q_r, v_r, a_r)``. Crocoddyl's RK nodes integrate the running cost over
  the node (RK4 quadrature of ``dt * l``), so a reference sampled at the node's start
  would lag by half a node (measured on this benchmark: 4.5e-3 rad tracking RMS with the
  node's start, 1.5e-6 rad with its midpoint); geosyn's running cost is a point cost at
  the node's start.
  Weights are scaled by ``2 / dt`` (Crocoddyl's ``0.5 r^T W r`` integrated over ``dt``
  equals geosyn's ``r^T w r`` per node);
- terminal node: ``|x - x_r(t + N dt)|^2_{W_N}`` (weights ``2 W_N``).

Every ``MPC_DT`` the problem is shifted one node (``ShootingProblem.circularAppend``,
the node that leaves gets the new last reference), ``x0`` set to the measured state and
BoxFDDP warm-started from the previous solution shifted by one node (last node repeated),
``WARM_ITERATIONS`` = 1 iteration (the first solve, from the reference, is a cold one of up
to ``COLD_ITERATIONS``). Between solves, at 1 kHz, the first control is applied with the
Riccati feedback of the last solve:
``tau = u_0 - K_0 (x - x^*(t))``, with ``x^*(t)`` the cubic Hermite interpolation of the
first planned interval (the same interpolation geosyn's MPC uses for its plan tracking).
The commanded torque is not clipped here (the plant saturates it and counts violations).
Crocoddyl runs single-threaded by default (`THREADS`).

Writes ``OUT.npz`` (arrays per run, keys ``<scenario>_N<N>_<field>``) and ``OUT.json``
(scalars: versions, model checks, per-run summaries).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import deque
from pathlib import Path

import crocoddyl
import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mpc_plant import (  # noqa: E402  (the shared plant sits next to this file)
    DURATION,
    MPC_DT,
    SCENARIOS,
    TICK,
    ReferenceSamples,
    initial_state,
    limit_violations,
    panda_model,
    rk4_step,
    run_closed_loop,
    tracking_rms,
)

# geosyn GeodesicMPC's defaults (controllers/mpc): per-node weights on |q - q_r|^2
# [1/rad^2], |v - v_r|^2 [s^2/rad^2], |tau - tau_r|^2 [1/(N m)^2], terminal |x - x_r|^2.
Q_WEIGHT = 1e4
V_WEIGHT = 1e1
TAU_WEIGHT = 1e-3
TERMINAL_WEIGHT = 1e5
WARM_ITERATIONS = 1
COLD_ITERATIONS = 50
# Crocoddyl's OpenMP threads (calc/calcDiff of the nodes). The PyPI wheel (libgomp) uses
# one per core, 2 here; measured on this loaded 2-core machine, a 1-iteration N = 10
# solve then took ~20 ms in the closed loop (its threads idle between solves and must be
# woken), ~0.9 ms single-threaded, ~0.55 ms with OMP_WAIT_POLICY=active (which keeps a
# core spinning). geosyn's solver is single-threaded: compare single-threaded.
THREADS = 1


class CrocoddylTrackingMPC:
    """BoxFDDP tracking MPC on RK4 nodes, warm-started by shifting (see the module docstring).

    Args:
        model: the Pinocchio model (armature, gravity and effort limits set).
        ref: the reference samples (1 kHz); must cover ``t + N dt`` for every solve.
        horizon: number of running nodes N.
        dt: node length and re-solve period [s].
        threads: Crocoddyl's OpenMP threads for the per-node calc/calcDiff (see `THREADS`).

    The constructor allocates the problem and solver; `policy` allocates small arrays.
    """

    def __init__(
        self,
        model: pin.Model,
        ref: ReferenceSamples,
        horizon: int,
        dt: float = MPC_DT,
        threads: int | None = None,
    ) -> None:
        self.model, self.ref, self.N, self.dt = model, ref, int(horizon), float(dt)
        self.nv = model.nv
        self.pdata = model.createData()
        self.tau_max = np.asarray(model.effortLimit, dtype=np.float64).copy()
        self.state = crocoddyl.StateMultibody(model)
        self.actuation = crocoddyl.ActuationModelFull(self.state)
        nodes = [self._running_node() for _ in range(self.N)]
        self.terminal, self.terminal_res = self._terminal_node()
        x0 = np.concatenate([ref.q[0], ref.v[0]])
        self.problem = crocoddyl.ShootingProblem(x0, [m for m, _, _ in nodes], self.terminal)
        # (model, data, state residual, control residual) in problem order, rotated with it.
        datas = self.problem.runningDatas
        self.nodes: deque = deque(
            (m, d, xr, ur) for (m, xr, ur), d in zip(nodes, datas, strict=True)
        )
        self.problem.nthreads = THREADS if threads is None else int(threads)
        self.solver = crocoddyl.SolverBoxFDDP(self.problem)
        self.t_solve = -np.inf
        self.xs: list[np.ndarray] = []
        self.us: list[np.ndarray] = []
        self.K0 = np.zeros((self.nv, 2 * self.nv))
        self.solve_call_time: list[float] = []

    # -- building ------------------------------------------------------------------
    def _running_node(self):
        n, s = self.nv, 2.0 / self.dt
        costs = crocoddyl.CostModelSum(self.state, n)
        xres = crocoddyl.ResidualModelState(self.state, np.zeros(2 * n), n)
        w_x = np.concatenate([np.full(n, s * Q_WEIGHT), np.full(n, s * V_WEIGHT)])
        costs.addCost(
            "track",
            crocoddyl.CostModelResidual(
                self.state, crocoddyl.ActivationModelWeightedQuad(w_x), xres
            ),
            1.0,
        )
        ures = crocoddyl.ResidualModelControl(self.state, np.zeros(n))
        w_u = np.full(n, s * TAU_WEIGHT)
        costs.addCost(
            "effort",
            crocoddyl.CostModelResidual(
                self.state, crocoddyl.ActivationModelWeightedQuad(w_u), ures
            ),
            1.0,
        )
        diff = crocoddyl.DifferentialActionModelFreeFwdDynamics(self.state, self.actuation, costs)
        diff.u_lb, diff.u_ub = -self.tau_max, self.tau_max
        node = crocoddyl.IntegratedActionModelRK(diff, crocoddyl.RKType.four, self.dt)
        if not (np.array_equal(node.u_ub, self.tau_max) and node.has_control_limits):
            raise RuntimeError("the torque limits did not reach the integrated action model")
        return node, xres, ures

    def _terminal_node(self):
        n = self.nv
        costs = crocoddyl.CostModelSum(self.state, n)
        xres = crocoddyl.ResidualModelState(self.state, np.zeros(2 * n), n)
        w = np.full(2 * n, 2.0 * TERMINAL_WEIGHT)
        costs.addCost(
            "terminal",
            crocoddyl.CostModelResidual(self.state, crocoddyl.ActivationModelWeightedQuad(w), xres),
            1.0,
        )
        diff = crocoddyl.DifferentialActionModelFreeFwdDynamics(self.state, self.actuation, costs)
        return crocoddyl.IntegratedActionModelRK(diff, crocoddyl.RKType.four, 0.0), xres

    # -- references ----------------------------------------------------------------
    def _set_running_reference(self, node: tuple, t_mid: float) -> None:
        _, _, xres, ures = node
        q, v, a = self.ref.at(t_mid)
        xres.reference = np.concatenate([q, v])
        ures.reference = pin.rnea(self.model, self.pdata, q, v, a)

    def _set_terminal_reference(self, t_end: float) -> None:
        q, v, _ = self.ref.at(t_end)
        self.terminal_res.reference = np.concatenate([q, v])

    # -- solving -------------------------------------------------------------------
    def solve(self, t: float, x: np.ndarray) -> int:
        """Re-plan from state ``x`` at time ``t`` [s]; returns the BoxFDDP iterations."""
        N, dt = self.N, self.dt
        cold = not self.xs
        if cold:
            for k, node in enumerate(self.nodes):
                self._set_running_reference(node, t + (k + 0.5) * dt)
            xs = [np.concatenate(self.ref.at(t + k * dt)[:2]) for k in range(N + 1)]
            us = [node[3].reference.copy() for node in self.nodes]
            max_iter = COLD_ITERATIONS
        else:
            shift = int(round((t - self.t_solve) / dt))
            if shift != 1:
                raise RuntimeError(f"re-solve after {shift} nodes; this runner shifts by one")
            leaving = self.nodes.popleft()
            self._set_running_reference(leaving, t + (N - 0.5) * dt)
            self.problem.circularAppend(leaving[0], leaving[1])
            self.nodes.append(leaving)
            xs = self.xs[1:] + [self.xs[-1]]
            us = self.us[1:] + [self.us[-1]]
            max_iter = WARM_ITERATIONS
        self._set_terminal_reference(t + N * dt)
        xs[0] = x
        self.problem.x0 = x
        start = time.perf_counter()
        self.solver.solve(xs, us, max_iter, False)
        self.solve_call_time.append(time.perf_counter() - start)
        self.xs = list(self.solver.xs)
        self.us = list(self.solver.us)
        self.K0 = np.array(self.solver.K[0])
        self.t_solve = t
        return int(self.solver.iter)

    def command(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``u_0 - K_0 (x - x^*(t))`` on the first planned interval (Hermite-interpolated)."""
        n, h = self.nv, self.dt
        s = min(max((t - self.t_solve) / h, 0.0), 1.0)
        x0, x1 = self.xs[0], self.xs[1]
        q0, v0, q1, v1 = x0[:n], x0[n:], x1[:n], x1[n:]
        s2, s3 = s * s, s * s * s
        q_p = (2 * s3 - 3 * s2 + 1) * q0 + (s3 - 2 * s2 + s) * h * v0
        q_p += (-2 * s3 + 3 * s2) * q1 + (s3 - s2) * h * v1
        v_p = ((6 * s2 - 6 * s) * q0 + (-6 * s2 + 6 * s) * q1) / h
        v_p += (3 * s2 - 4 * s + 1) * v0 + (3 * s2 - 2 * s) * v1
        dx = np.concatenate([q - q_p, v - v_p])
        return self.us[0] - self.K0 @ dx

    def policy(self, k: int, t: float, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, int]:
        """The closed-loop controller of `mpc_plant.run_closed_loop`."""
        iters = -1
        if k % int(round(self.dt / TICK)) == 0:
            iters = self.solve(t, np.concatenate([q, v]))
        return self.command(t, q, v), iters


# -- checks ------------------------------------------------------------------------
def check_dynamics(model: pin.Model, ref: ReferenceSamples, count: int = 50) -> float:
    """Max |Crocoddyl's acceleration - pin.aba| [rad/s^2] on reference states and random
    torques (large with pin 4.1.0, see setup_crocoddyl.sh)."""
    state = crocoddyl.StateMultibody(model)
    diff = crocoddyl.DifferentialActionModelFreeFwdDynamics(
        state, crocoddyl.ActuationModelFull(state), crocoddyl.CostModelSum(state, model.nv)
    )
    data, pdata = diff.createData(), model.createData()
    rng = np.random.default_rng(0)
    err = 0.0
    for i in np.linspace(0, ref.t.size - 1, count).astype(int):
        u = pin.rnea(model, pdata, ref.q[i], ref.v[i], ref.a[i]) + rng.normal(size=model.nv)
        diff.calc(data, np.concatenate([ref.q[i], ref.v[i]]), u)
        err = max(
            err, float(np.abs(data.xout - pin.aba(model, pdata, ref.q[i], ref.v[i], u)).max())
        )
    return err


def check_model(model: pin.Model, path: Path) -> dict[str, float]:
    """Compare geosyn's M(q) (from ``path``: ``q`` (K, n), ``M`` (K, n, n)) with this side's
    ``pin.crba`` and Crocoddyl's own ``Fu = M^-1`` (relative max errors), and the plant
    step of geosyn's venv (``v``, ``tau``, ``x_next``) with this venv's (max abs error)."""
    with np.load(path) as f:
        qs, ms = np.array(f["q"]), np.array(f["M"])
        vs, taus, x_next = np.array(f["v"]), np.array(f["tau"]), np.array(f["x_next"])
    state = crocoddyl.StateMultibody(model)
    diff = crocoddyl.DifferentialActionModelFreeFwdDynamics(
        state, crocoddyl.ActuationModelFull(state), crocoddyl.CostModelSum(state, model.nv)
    )
    data, pdata = diff.createData(), model.createData()
    crba_err = croc_err = 0.0
    for q, m_geo in zip(qs, ms, strict=True):
        m = pin.crba(model, pdata, q)
        m = np.triu(m) + np.triu(m, 1).T
        scale = float(np.abs(m_geo).max())
        crba_err = max(crba_err, float(np.abs(m - m_geo).max()) / scale)
        x, u = np.concatenate([q, np.zeros(model.nv)]), np.zeros(model.nv)
        diff.calc(data, x, u)
        diff.calcDiff(data, x, u)
        croc_err = max(croc_err, float(np.abs(np.linalg.inv(data.Fu) - m_geo).max()) / scale)
    step_err = 0.0
    for q, v, tau, x_geo in zip(qs, vs, taus, x_next, strict=True):
        x = np.concatenate(rk4_step(model, pdata, q, v, tau, TICK))
        step_err = max(step_err, float(np.abs(x - x_geo).max()))
    return {
        "mass_matrix_rel_err_crba": crba_err,
        "mass_matrix_rel_err_crocoddyl": croc_err,
        "plant_step_abs_err": step_err,
    }


# -- runs --------------------------------------------------------------------------
def run_one(
    model: pin.Model, ref: ReferenceSamples, scenario: str, horizon: int, threads: int = THREADS
) -> dict:
    """One closed-loop run: arrays and a summary."""
    q0, v0 = initial_state(scenario, ref)
    mpc = CrocoddylTrackingMPC(model, ref, horizon, threads=threads)
    roll = run_closed_loop(model, q0, v0, DURATION, mpc.policy)
    ticks_over, max_excess = limit_violations(roll.tau_cmd, mpc.tau_max)
    warm = roll.solve_time[1:]
    summary = {
        "scenario": scenario,
        "horizon": horizon,
        "threads": mpc.problem.nthreads,
        "solves": int(roll.solve_time.size),
        "cold_solve_ms": 1e3 * float(roll.solve_time[0]),
        "cold_iterations": int(roll.iterations[0]),
        "median_ms": 1e3 * float(np.median(warm)),
        "p99_ms": 1e3 * float(np.percentile(warm, 99)),
        "cpu_median_ms": 1e3 * float(np.median(roll.solve_cpu[1:])),
        "solver_call_median_ms": 1e3 * float(np.median(mpc.solve_call_time[1:])),
        "iterations_median": float(np.median(roll.iterations[1:])),
        "tracking_rms": tracking_rms(roll, ref),
        "ticks_over_limit": ticks_over,
        "max_limit_excess_rel": max_excess,
    }
    arrays = {
        "solve_time": roll.solve_time,
        "solve_cpu": roll.solve_cpu,
        "solver_call_time": np.asarray(mpc.solve_call_time),
        "iterations": roll.iterations,
        "tau_cmd": roll.tau_cmd,
        "q": roll.q,
        "v": roll.v,
    }
    return {"summary": summary, "arrays": arrays}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--reference", type=Path, required=True, help="reference .npz")
    parser.add_argument("--out", type=Path, required=True, help="results .npz (+ .json)")
    parser.add_argument("--horizon", type=int, nargs="+", default=[10, 40])
    parser.add_argument("--scenario", nargs="+", default=list(SCENARIOS), choices=SCENARIOS)
    parser.add_argument(
        "--model-check", type=Path, help="geosyn's M(q) and plant-step samples (.npz)"
    )
    parser.add_argument("--threads", type=int, default=THREADS, help="Crocoddyl's nthreads")
    args = parser.parse_args(argv)

    ref = ReferenceSamples.load(args.reference)
    model = panda_model()
    info: dict = {
        "crocoddyl": crocoddyl.__version__,
        "pinocchio": pin.__version__,
        "numpy": np.__version__,
        "dynamics_err_vs_aba": check_dynamics(model, ref),
        "runs": [],
    }
    if args.model_check is not None:
        info.update(check_model(model, args.model_check))
    arrays: dict[str, np.ndarray] = {}
    for horizon in args.horizon:
        if (DURATION + horizon * MPC_DT) > ref.t[-1] + 1e-9:
            raise SystemExit(
                f"croc_runner: the reference ends at {ref.t[-1]:.3f} s; N={horizon} needs "
                f"{DURATION + horizon * MPC_DT:.3f} s"
            )
        for scenario in args.scenario:
            res = run_one(model, ref, scenario, horizon, args.threads)
            info["runs"].append(res["summary"])
            for key, val in res["arrays"].items():
                arrays[f"{scenario}_N{horizon}_{key}"] = val
    args.out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(args.out, **arrays)
    args.out.with_suffix(".json").write_text(json.dumps(info, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
