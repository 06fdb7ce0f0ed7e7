"""Issue 23, bounded MPC solves: the fatrop tick at ``max_iter`` 10^6 against its 50 ms
budget, and what the worker thread costs a normal solve, each against a reference timed
in the same run.

Run: ``.venv/bin/python benchmarks/hardening_solves.py``. Prints wall and CPU times and
ratios; no assertions. Figures depend on the machine's load.

- Tick (planar2, horizon 10, acceleration control, exact Hessian): worst of 10 ticks with
  fatrop made endless (plugin ``tol`` 1e-300, no acceptable stop) at ``max_iter`` 10^6
  and ``max_solve_time`` 0.05 s; reference: the default settings (``max_iter`` 50).
- Overhead: one warm solve and its statistics through `BoundedSolver` (the worker
  thread) against the same CasADi function and ``stats()`` called directly (what
  `ShootingNLP.run` did before), alternating A/B, best of 7 repeats each.
"""

from __future__ import annotations

import time

import numpy as np
from _timing import per_call

from geosyn.controllers.mpc import GeodesicMPC, NLPOptions
from geosyn.controllers.reference import GeodesicReference
from geosyn.metrics import KineticEnergyMetric
from geosyn.robots import load_robot
from geosyn.synergies.synergy import GeodesicSynergy

Q0 = np.array([0.3, -0.4])


def mpc(options: NLPOptions, budget: float) -> GeodesicMPC:
    robot = load_robot("planar2")
    metric = KineticEnergyMetric(robot)
    ref = GeodesicReference(GeodesicSynergy(metric, Q0, np.array([0.4, 0.4])), duration=1.0)
    m = GeodesicMPC(robot, metric, horizon=10, dt=0.02, hessian="exact", reference=ref,
                    solver=options, max_solve_time=budget)  # fmt: skip
    m.reset(Q0, np.zeros(2))
    return m


def worst_tick(m: GeodesicMPC) -> tuple[float, float, int]:
    """(wall, CPU, iterations) of the worst of 10 ticks, 20 ms apart."""
    worst = (0.0, 0.0, 0)
    for k in range(10):
        w, c = time.perf_counter(), time.process_time()
        m.compute(0.02 * k, Q0 + 0.1, np.zeros(2))
        wall, cpu = time.perf_counter() - w, time.process_time() - c
        if wall > worst[0]:
            worst = (wall, cpu, m.diagnostics.iterations)
    return worst


def main() -> None:
    endless = {"tol": 1e-300, "acceptable_iter": 10**9}
    ref = worst_tick(mpc(NLPOptions("fatrop"), 0.05))
    big = worst_tick(mpc(NLPOptions("fatrop", max_iter=10**6, plugin_options=endless), 0.05))
    print(f"tick, default max_iter 50:   {ref[0] * 1e3:6.1f} ms wall {ref[1] * 1e3:6.1f} ms CPU"
          f" ({ref[2]} iterations)")  # fmt: skip
    print(f"tick, max_iter 1e6, endless: {big[0] * 1e3:6.1f} ms wall {big[1] * 1e3:6.1f} ms CPU"
          f" ({big[2]} iterations; budget 50 ms)")  # fmt: skip

    m = mpc(NLPOptions("fatrop"), 1.0)
    m.compute(0.0, Q0 + 0.01, np.zeros(2))
    bounded = m.backend.nlp.solver
    raw = bounded.first
    p = m.problem_parameters(0.0, np.concatenate([Q0 + 0.01, np.zeros(2)]))[0]
    nlp = m.backend.nlp
    x0 = nlp.pack(np.zeros((nlp.N + 1, 4)), np.zeros((nlp.N, 2)))
    args = {"p": p, "lbx": nlp.lbx, "ubx": nlp.ubx, "lbg": nlp.lbg, "ubg": nlp.ubg, "x0": x0}
    times = {"direct": [], "worker": []}
    for _ in range(3):  # alternating A/B
        times["direct"].append(per_call(lambda: (raw(**args), raw.stats())))
        times["worker"].append(per_call(lambda: bounded(**args)))
    d, w = min(times["direct"]), min(times["worker"])
    print(f"solve direct {d * 1e6:7.1f} us, through BoundedSolver {w * 1e6:7.1f} us:"
          f" +{(w - d) * 1e6:.1f} us ({w / d:.3f} x)")  # fmt: skip


if __name__ == "__main__":
    main()
