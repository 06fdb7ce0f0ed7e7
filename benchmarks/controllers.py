"""Benchmark of the controllers on panda: per-tick wall time, median and p99.

Run: ``.venv/bin/python benchmarks/controllers.py [--quick]``. Prints figures and ratios;
no assertions. Timings are wall-clock and depend on the machine's load.

Scenario: the panda (gravity on) tracks a geodesic synergy from mid-range with 0.6 rad/s
on every joint, slowed by 1.5 (1.5 s of motion), on a Pinocchio plant (pin.aba + RK4) at
1 kHz for 1.6 s. Every controller sees the same states in its own closed loop; each
``compute`` call is timed (validation, clipping and diagnostics included).

- ComputedTorque, RiemannianPD, QPController: every 1 ms tick.
- GeodesicMPC (N = 40, dt = 20 ms, warm-started by shifting the last solution): the
  solve ticks (every 20 ms) and, separately, the ticks in between (plan tracking only).
  Variants: fatrop with acceleration control, fatrop with torque control (RK4 on the
  ABA), IPOPT with torque control; all with Gauss-Newton Hessians of compiled per-stage
  dynamics (see `geosyn.controllers.mpc`).
- Naive reference, same OCP (`build_naive_ipopt`, `solve_naive`): CasADi + IPOPT on the
  MX graph without SX expansion, exact Hessian, cold start from the current state (no
  warm start), solved at a few states of the closed loop; printed with the ratio
  naive / warm-started solve tick.
"""

from __future__ import annotations

import sys
import time

import casadi as ca
import numpy as np

from geosyn.controllers.computed_torque import ComputedTorque
from geosyn.controllers.mpc import GeodesicMPC, MPCPlan
from geosyn.controllers.mpc.nlp.problem import ShootingNLP, transcribe
from geosyn.controllers.plant import PinocchioPlant
from geosyn.controllers.qp import QPController
from geosyn.controllers.reference import GeodesicReference
from geosyn.controllers.riemannian_pd import RiemannianPD
from geosyn.metrics import KineticEnergyMetric
from geosyn.robots import load_robot
from geosyn.synergies.synergy import GeodesicSynergy

SIM_TIME = 1.6  # [s]


def scenario():
    robot = load_robot("panda")
    metric = KineticEnergyMetric(robot)
    q0 = 0.5 * (robot.q_min + robot.q_max)
    v0 = np.full(robot.nv, 0.6)
    ref = GeodesicReference(
        GeodesicSynergy(metric, q0, v0), time_scale=1.5, duration=1.0, steps=200
    )
    return robot, metric, ref, q0, v0 / 1.5


def build_naive_ipopt(mpc: GeodesicMPC) -> ShootingNLP:
    """The tracking OCP of ``mpc`` for IPOPT on an MX graph, not expanded, exact Hessian.

    The same problem (dynamics, costs, bounds) as the controller's, transcribed with one
    plain call per stage and solved cold with IPOPT's defaults besides the tolerance: the
    reference point of the benchmark.
    """
    ocp = mpc.ocp
    problem = ocp.problem(ocp.dynamics(gravity=True), effort=mpc.effort, gravity=True)
    graph = transcribe(problem, ca.MX, mapped=False)
    opts = {
        "expand": False,
        "print_time": False,
        "error_on_fail": False,
        "ipopt": {"print_level": 0, "sb": "yes", "tol": mpc.solver_options.tol},
    }
    solver = ca.nlpsol("mpc_naive", "ipopt", graph.nlp, opts)
    return ShootingNLP.from_problem(problem, graph, solver, None)


def solve_naive(
    mpc: GeodesicMPC, nlp: ShootingNLP, t: float, q: np.ndarray, v: np.ndarray
) -> MPCPlan:
    """Cold solve of the naive build from the state ``(q, v)`` [rad, rad/s] at ``t`` [s]."""
    x_init = np.concatenate([q, v])
    p, _ = mpc.problem_parameters(t, x_init)
    guess = {"x0": nlp.pack(np.tile(x_init, (mpc.N + 1, 1)), np.zeros((mpc.N, mpc.nv)))}
    start = time.perf_counter()
    res = nlp.run(nlp.solver, p, guess)
    elapsed = time.perf_counter() - start
    return MPCPlan(t, res.x, res.u, res.tau, res.status, res.iterations, res.success, elapsed)


def run(controller, robot, ref, q0, v0):
    """Closed loop: per-tick wall times [s], RMS error [rad], states, CPU times [s], iterations."""
    controller.set_reference(ref)
    controller.reset(q0, v0)
    plant = PinocchioPlant(robot, dt=1e-3)
    plant.reset(q0, v0)
    steps = int(round(SIM_TIME / plant.dt))
    times = np.empty(steps)
    cpu = np.empty(steps)
    iters = np.empty(steps, dtype=int)
    err2 = 0.0
    states = []
    q, v, t = q0.copy(), v0.copy(), 0.0
    for k in range(steps):
        t0, c0 = time.perf_counter(), time.process_time()
        tau = controller.compute(t, q, v)
        times[k] = time.perf_counter() - t0
        cpu[k] = time.process_time() - c0
        iters[k] = controller.diagnostics.iterations
        states.append((t, q.copy(), v.copy()))
        q, v = plant.step(tau)
        t = plant.t
        err2 += float(np.sum((q - ref.sample(t).q) ** 2))
    rms = (err2 / (steps * robot.nv)) ** 0.5
    return times, rms, states, cpu, iters


def fmt(times: np.ndarray) -> str:
    return (
        f"median {1e6 * np.median(times):9.1f} us   p99 {1e6 * np.percentile(times, 99):9.1f} us"
        f"   (n={times.size})"
    )


def main() -> None:
    quick = "--quick" in sys.argv
    robot, metric, ref, q0, v0 = scenario()
    print(f"panda, nv={robot.nv}, 1 kHz Pinocchio plant, {SIM_TIME} s geodesic synergy tracking")
    print("machine load at start:", open("/proc/loadavg").read().split()[:3])
    simple = [
        ("ComputedTorque", ComputedTorque(robot, kp=400.0, kd=40.0, metric=metric)),
        ("RiemannianPD", RiemannianPD(robot, lam=20.0, k=20.0, metric=metric)),
        ("QPController", QPController(robot, kp=400.0, kd=40.0, dt=1e-3, metric=metric)),
    ]
    for name, ctrl in simple:
        times, rms, *_ = run(ctrl, robot, ref, q0, v0)
        print(f"{name:34s} {fmt(times)}   rms {rms:.1e} rad")

    variants = [
        ("fatrop", "acceleration", "acceleration"),
        ("fatrop", "acceleration", "torque"),
        ("fatrop", "torque", "torque"),
    ]
    if not quick:
        variants.append(("ipopt", "acceleration", "acceleration"))
    for solver, control, effort in variants:
        t0 = time.perf_counter()
        mpc = GeodesicMPC(
            robot, metric, horizon=40, dt=0.02, solver=solver, control=control, effort=effort
        )
        build = time.perf_counter() - t0
        times, rms, states, cpu, iters = run(mpc, robot, ref, q0, v0)
        solve_ticks = times[::20]
        warm = solve_ticks[1:]  # the first solve is cold
        between = np.delete(times, np.arange(0, times.size, 20))
        iters = iters[::20][1:]
        label = f"GeodesicMPC {solver}/{control}/{effort}"
        print(f"{label:34s} {fmt(warm)}   rms {rms:.1e} rad   (solve ticks, warm)")
        print(
            f"{'':34s} iterations median {np.median(iters):.0f}, max {np.max(iters)}; "
            f"process CPU per solve tick median {1e3 * np.median(cpu[::20][1:]):.1f} ms"
        )
        print(
            f"{'':34s} cold first solve {1e3 * solve_ticks[0]:.1f} ms, build {build:.1f} s, "
            f"fallbacks {mpc.diagnostics.fallback_count}"
        )
        print(f"{'  between solves (plan tracking)':34s} {fmt(between)}")
        # The naive build of the same OCP, cold, at a few states of this closed loop.
        n_naive = 2 if quick or control == "torque" else 3
        picks = np.linspace(0, len(states) - 1, n_naive + 2).astype(int)[1:-1]
        picks = (picks // 20) * 20  # solve ticks
        t0 = time.perf_counter()
        naive_nlp = build_naive_ipopt(mpc)
        naive_build = time.perf_counter() - t0
        naive = []
        for i in picks:
            t, q, v = states[i]
            plan = solve_naive(mpc, naive_nlp, t, q, v)
            naive.append((plan.solve_time, plan.iterations, plan.success))
        nt = np.array([x[0] for x in naive])
        print(
            f"{'  naive IPOPT (MX, no expand, cold)':34s} median {1e3 * np.median(nt):9.1f} ms"
            f"   iterations {[x[1] for x in naive]}, success {[x[2] for x in naive]}, "
            f"build {naive_build:.1f} s"
        )
        print(f"{'  ratio naive / warm median':34s} {np.median(nt) / np.median(warm):9.1f} x")


if __name__ == "__main__":
    main()
