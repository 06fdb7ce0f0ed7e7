"""Torque-level geodesic-tracking MPC: geosyn's GeodesicMPC against Crocoddyl's BoxFDDP.

Setup (once; idempotent)::

    bash benchmarks/setup_crocoddyl.sh     # makes .venv-croc: `pip install crocoddyl numpy`,
                                           # then `pip install pin==4.0.0` (see below)

Run (in geosyn's venv)::

    .venv/bin/python benchmarks/mpc_vs_crocoddyl.py [--rounds 3] [--horizon 10 40]
        [--scenario on_reference offset_at_rest] [--skip-geosyn] [--croc-python PATH]
        [--croc-threads 1] [--save summaries.json] [--geosyn-option tau_weight=1e-2 ...]

Crocoddyl comes from PyPI into its own venv (``.venv-croc``, gitignored), never into
geosyn's: ``pip install crocoddyl`` pulls pin 4.1.0, with which the crocoddyl 3.2.1 wheel's
forward dynamics are wrong (they drop gravity: 20-50 rad/s^2 off ``pin.aba`` on the
Panda), so the setup
script pins ``pin==4.0.0`` and checks Crocoddyl's accelerations against ``pin.aba``.

What is compared, on the same problem and the same plant:

- Reference: a geodesic of the Panda's kinetic-energy metric from geosyn's ``exp``
  (``REFERENCE_Q0``, ``REFERENCE_V0``), sampled at 1 kHz (t, q, v, a) and saved once to
  ``benchmarks/data/panda_geodesic_reference.npz``. It is ``DURATION`` = 1.5 s tracked
  plus 0.8 s beyond, so that an N = 40 horizon (0.8 s) never looks past its end.
- Plant: ``benchmarks/mpc_plant.py`` (numpy + pinocchio only, imported by both venvs):
  geosyn's ``"panda"`` model (fingers locked, armature 0.1 kg m^2, gravity on), 1 kHz
  ``pin.aba`` + RK4, commanded torque saturated at the limits by the actuator. The
  Crocoddyl side's M(q) (``pin.crba`` and Crocoddyl's own ``Fu = M^-1``), its
  accelerations against ``pin.aba`` and its plant step are checked against geosyn's side
  through an .npz file; the run stops if they differ.
- Crocoddyl (``benchmarks/croc_runner.py``, a subprocess in ``.venv-croc``): full state,
  torque controls, RK4 nodes, BoxFDDP, 1 warm-started iteration per solve, first control
  plus Riccati feedback ``-K_0 dx`` between solves, single-threaded like geosyn's solver
  (``--croc-threads``; see ``croc_runner.THREADS`` for why); see its docstring.
- geosyn (`run_geosyn`): ``GeodesicMPC(control="torque")`` with its defaults (since
  issue 21 the default torque-level solver is box-DDP, ``solver=None``, and the
  joint-limit guard is on): box-DDP whose backward pass (RK4-on-ABA Jacobians, Riccati
  recursion, box QP) is the hand-written C of `geosyn.controllers.mpc.ddp.native`
  (``DDPOptions(backward="native")``, the default; the summary's ``solver`` says which
  backward pass ran), one warm-started iteration per solve, its Riccati feedback saturated at the
  torque limits between solves (``effort="torque"``), every torque through the
  joint-limit guard (`geosyn.controllers.limit_guard`; its cost is in the timed call).
  ``--geosyn-option solver=fatrop`` times the interior-point solver instead
  (Gauss-Newton Hessian of the compiled RK4 step), ``joint_limit_guard=False`` the
  unguarded controller.
- Both: N in {10, 40}, dt = 20 ms, re-solve every 20 ms, the same weights (geosyn's
  defaults), costs tracking (q, v) of the reference and regularising the torque around
  the reference's inverse dynamics, torque limits. Scenarios: ``on_reference`` (start on
  the reference) and ``offset_at_rest`` (every joint 0.1 rad off, at rest: the torque
  limits become active). geosyn's OCP also limits q and v (hard bounds for fatrop, stiff
  penalties for ddp; inactive here: the reference stays >= 0.7 rad inside the joint
  limits), Crocoddyl's only the torques.
- Rounds: ``--rounds`` (3) rounds alternating the order (Crocoddyl first, then geosyn
  first, ...). A solve's time is the wall time of the whole controller call at a re-solve
  tick (reference update, warm start, solver, first command); the first (cold) solve of
  each run is left out of median and p99. Tracking RMS is over all joints and 1 kHz
  ticks of the 1.5 s run; "ticks over" counts ticks whose commanded (unclipped) torque
  exceeds a limit by more than 1e-6 N m; "joint-limit violations" counts the plant's
  states (1 kHz) outside the model's position limits or over its velocity limits.

Timings are wall-clock and depend on the machine's load; numbers go to RESULTS.md.
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from mpc_plant import (  # noqa: E402  (the shared plant sits next to this file)
    DURATION,
    MPC_DT,
    SCENARIOS,
    TICK,
    ReferenceSamples,
    Rollout,
    initial_state,
    limit_violations,
    panda_model,
    rk4_step,
    run_closed_loop,
    tracking_rms,
)
from mpc_table import table  # noqa: E402  (next to this file)

REFERENCE = HERE / "data" / "panda_geodesic_reference.npz"
RUNNER = HERE / "croc_runner.py"
DEFAULT_CROC_PYTHON = HERE.parent / ".venv-croc" / "bin" / "python"
MAX_HORIZON = 40  # longest horizon the saved reference covers (stages)
# Panda "ready" pose and a velocity that keeps the 2.3 s geodesic >= 0.7 rad inside the
# joint limits, with |v| <= 0.75 rad/s and reference torques <= 25 % of the limits.
REFERENCE_Q0 = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)  # [rad]
REFERENCE_V0 = (0.4, 0.3, -0.3, 0.4, 0.5, -0.4, 0.6)  # [rad/s]


# -- reference and model checks (geosyn's venv) ------------------------------------
def make_reference(path: Path = REFERENCE) -> ReferenceSamples:
    """Integrate the reference geodesic with geosyn's ``exp`` and save it (1 kHz)."""
    from geosyn.metrics import KineticEnergyMetric, exp
    from geosyn.robots import load_robot

    robot = load_robot("panda")
    metric = KineticEnergyMetric(robot)
    total = DURATION + MAX_HORIZON * MPC_DT
    steps = int(round(total / TICK))
    geo = exp(metric, np.array(REFERENCE_Q0), np.array(REFERENCE_V0), duration=total, steps=steps)
    a = np.array([metric.geodesic_acceleration(q, v) for q, v in zip(geo.q, geo.v, strict=True)])
    t = np.arange(steps + 1) * TICK
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        path,
        t=t,
        q=geo.q,
        v=geo.v,
        a=a,
        q0=np.array(REFERENCE_Q0),
        v0=np.array(REFERENCE_V0),
        tracked_duration=DURATION,
    )
    return ReferenceSamples(t, np.asarray(geo.q), np.asarray(geo.v), a)


def write_model_check(path: Path, ref: ReferenceSamples, count: int = 20) -> float:
    """Save geosyn's M(q) at reference and random configurations, and one plant step from
    each (random v, tau) made with this venv's pinocchio, for the Crocoddyl side to compare;
    return the relative difference between geosyn's metric and this venv's plant model."""
    from geosyn.metrics import KineticEnergyMetric
    from geosyn.robots import load_robot

    robot = load_robot("panda")
    metric = KineticEnergyMetric(robot)
    rng = np.random.default_rng(1)
    idx = np.linspace(0, ref.t.size - 1, count // 2).astype(int)
    lo, hi = robot.q_min, robot.q_max
    qs = np.vstack([ref.q[idx], rng.uniform(lo, hi, size=(count - idx.size, robot.nv))])
    ms = np.array([np.asarray(metric.G(q), dtype=np.float64) for q in qs])
    plant = panda_model()
    data = plant.createData()
    vs = rng.normal(size=qs.shape)
    taus = 0.5 * rng.uniform(-1.0, 1.0, size=qs.shape) * np.asarray(plant.effortLimit)
    steps = [
        np.concatenate(rk4_step(plant, data, q, v, tau, TICK))
        for q, v, tau in zip(qs, vs, taus, strict=True)
    ]
    np.savez(path, q=qs, M=ms, v=vs, tau=taus, x_next=np.array(steps))
    err = 0.0
    for q, m in zip(qs, ms, strict=True):
        mp = pin.crba(plant, data, q)
        mp = np.triu(mp) + np.triu(mp, 1).T
        err = max(err, float(np.abs(mp - m).max() / np.abs(m).max()))
    return err


# -- the two sides ------------------------------------------------------------------
def run_crocoddyl(
    croc_python: Path,
    horizons: list[int],
    scenarios: list[str],
    work: Path,
    tag: str,
    model_check: Path | None = None,
    threads: int = 1,
) -> dict:
    """Run ``croc_runner.py`` in the Crocoddyl venv; its JSON summary plus the arrays."""
    out = work / f"croc_{tag}.npz"
    cmd = [
        str(croc_python),
        str(RUNNER),
        "--reference",
        str(REFERENCE),
        "--out",
        str(out),
        "--horizon",
        *map(str, horizons),
        "--scenario",
        *scenarios,
        "--threads",
        str(threads),
    ]
    if model_check is not None:
        cmd += ["--model-check", str(model_check)]
    # The runner must not see geosyn's venv (its pin 4.1.0 breaks Crocoddyl's wheel).
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"croc_runner failed ({done.returncode}):\n{done.stderr[-3000:]}")
    info = json.loads(out.with_suffix(".json").read_text())
    with np.load(out) as f:
        info["arrays"] = {k: np.array(f[k]) for k in f.files}
    return info


class GeosynSide:
    """geosyn's torque-level MPC, built once per horizon and reused across rounds."""

    def __init__(self, ref: ReferenceSamples, options: dict | None = None) -> None:
        from geosyn.controllers import JointTrajectoryReference
        from geosyn.metrics import KineticEnergyMetric
        from geosyn.robots import load_robot

        self.robot = load_robot("panda")
        self.metric = KineticEnergyMetric(self.robot)
        self.reference = JointTrajectoryReference(ref.t, ref.q, ref.v, ref.a)
        self.options = dict(options or {})  # GeodesicMPC keyword arguments (--geosyn-option)
        self.mpcs: dict[int, object] = {}
        self.build_time: dict[int, float] = {}

    def mpc(self, horizon: int):
        if horizon not in self.mpcs:
            from geosyn.controllers import GeodesicMPC

            start = time.perf_counter()
            options = {"control": "torque", **self.options}
            self.mpcs[horizon] = GeodesicMPC(
                self.robot,
                self.metric,
                horizon=horizon,
                dt=MPC_DT,
                reference=self.reference,
                **options,
            )
            self.build_time[horizon] = time.perf_counter() - start
        return self.mpcs[horizon]


# ==== geosyn's side: to be finished for issue 13 (its new torque-level MPC) ==========
def run_geosyn(side: GeosynSide, ref: ReferenceSamples, scenario: str, horizon: int) -> dict:
    """geosyn's torque-level MPC on the shared plant: a summary and arrays like the runner's.

    The controller is ``GeodesicMPC(control="torque", **options)`` (its default solver
    unless ``--geosyn-option`` says otherwise) with its default weights; its own plan
    following runs between solves (ddp: ``u_0 + K_0 dx`` saturated at the torque limits;
    fatrop/ipopt: planned torque + M(q) PD). The command recorded is the controller's
    output before `Controller.compute` clips it (``last_unclipped_torque``); the summary
    also counts the ticks whose command sits at a limit (``ticks_at_limit``).
    """
    mpc = side.mpc(horizon)
    q0, v0 = initial_state(scenario, ref)
    mpc.reset(q0, v0)

    def policy(k: int, t: float, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, int]:
        mpc.compute(t, q, v)
        return mpc.last_unclipped_torque, mpc.diagnostics.iterations

    model = panda_model()
    roll = run_closed_loop(model, q0, v0, DURATION, policy)
    summary = summarize(scenario, horizon, roll, ref, model)
    at_limit = np.abs(roll.tau_cmd) >= np.asarray(model.effortLimit) * (1.0 - 1e-12)
    summary["ticks_at_limit"] = int(np.count_nonzero(at_limit.any(axis=1)))
    summary["joint_limit_violations"], summary["max_joint_limit_excess"] = joint_limit_violations(
        roll, model
    )
    summary["guard_ticks"] = int(mpc.command.count)
    options = mpc.solver_options
    backward = getattr(options, "backward", None)  # DDPOptions: "native" or "casadi"
    summary["solver"] = options.name + (f" ({backward} backward)" if backward else "")
    return summary


def joint_limit_violations(roll: Rollout, model: pin.Model) -> tuple[int, float]:
    """States of the closed loop outside the position limits or over the velocity limits
    (count), and the largest excess ([rad] or [rad/s]; 0 when none)."""
    excess = np.concatenate(
        [
            roll.q - np.asarray(model.upperPositionLimit),
            np.asarray(model.lowerPositionLimit) - roll.q,
            np.abs(roll.v) - np.asarray(model.velocityLimit),
        ],
        axis=1,
    )
    return int(np.count_nonzero((excess > 0.0).any(axis=1))), float(max(0.0, excess.max()))


def summarize(
    scenario: str,
    horizon: int,
    roll: Rollout,
    ref: ReferenceSamples,
    model: pin.Model,
) -> dict:
    ticks_over, excess = limit_violations(roll.tau_cmd, np.asarray(model.effortLimit))
    return {
        "scenario": scenario,
        "horizon": horizon,
        "cold_solve_ms": 1e3 * float(roll.solve_time[0]),
        "median_ms": 1e3 * float(np.median(roll.solve_time[1:])),
        "p99_ms": 1e3 * float(np.percentile(roll.solve_time[1:], 99)),
        "cpu_median_ms": 1e3 * float(np.median(roll.solve_cpu[1:])),
        "iterations_median": float(np.median(roll.iterations[1:])),
        "tracking_rms": tracking_rms(roll, ref),
        "ticks_over_limit": ticks_over,
        "max_limit_excess_rel": excess,
        "solve_time": roll.solve_time,
        "solve_cpu": roll.solve_cpu,
        "iterations": roll.iterations,
    }


def check_crocoddyl_side(info: dict) -> None:
    """Stop when Crocoddyl's model, dynamics or plant differ from geosyn's side."""
    limits = {
        "dynamics_err_vs_aba": 1e-8,  # [rad/s^2]; 20-50 with pin 4.1.0
        "mass_matrix_rel_err_crba": 1e-12,
        "mass_matrix_rel_err_crocoddyl": 1e-10,  # through a matrix inverse
        "plant_step_abs_err": 1e-12,
    }
    bad = {k: info.get(k) for k, lim in limits.items() if not info.get(k, np.inf) <= lim}
    if bad:
        raise SystemExit(f"Crocoddyl's side differs from geosyn's: {bad} (limits {limits})")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--horizon", type=int, nargs="+", default=[10, 40])
    parser.add_argument("--scenario", nargs="+", default=list(SCENARIOS), choices=SCENARIOS)
    parser.add_argument("--skip-geosyn", action="store_true", help="run Crocoddyl only")
    parser.add_argument("--croc-python", type=Path, default=DEFAULT_CROC_PYTHON)
    parser.add_argument(
        "--croc-threads",
        type=int,
        default=1,
        help="Crocoddyl's OpenMP threads (1: like geosyn's solver; see croc_runner.THREADS)",
    )
    parser.add_argument("--save", type=Path, help="write all summaries to this JSON file")
    parser.add_argument(
        "--geosyn-option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a GeodesicMPC keyword argument for geosyn's side, e.g. tau_weight=1e-2 or"
        " solver=fatrop (repeatable; the value is parsed as a Python literal; solver"
        " options such as tol are DDPOptions/NLPOptions fields, not keywords)",
    )
    args = parser.parse_args(argv)
    if max(args.horizon) > MAX_HORIZON:
        parser.error(f"--horizon at most {MAX_HORIZON} (the saved reference's lookahead)")
    if not args.croc_python.is_file():
        raise SystemExit(
            f"no Crocoddyl venv at {args.croc_python}: run `bash benchmarks/setup_crocoddyl.sh`"
        )

    if REFERENCE.is_file():
        ref = ReferenceSamples.load(REFERENCE)
    else:
        print(f"creating the reference {REFERENCE.relative_to(HERE.parent)} (geosyn exp)")
        ref = make_reference()
    results: dict[tuple[str, int, str], list[dict]] = {}
    options: dict = {}  # GeodesicMPC's defaults (torque level: box-DDP and the guard)
    for item in args.geosyn_option:
        key, _, value = item.partition("=")
        try:
            options[key] = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            options[key] = value  # a plain string, e.g. solver=ipopt
    side = None if args.skip_geosyn else GeosynSide(ref, options)
    croc_info: dict = {}
    with tempfile.TemporaryDirectory(prefix="mpc_vs_croc_") as tmp:
        work = Path(tmp)
        mass = work / "geosyn_model_check.npz"
        plant_err = write_model_check(mass, ref)
        print(f"M(q): panda_model() vs geosyn's metric, max rel. diff {plant_err:.1e}")
        if plant_err > 1e-12:
            raise SystemExit("the benchmark's Panda model is not geosyn's (M(q) differs)")
        if side is not None:
            for horizon in args.horizon:
                print(f"building geosyn's torque MPC, N={horizon} ...", flush=True)
                side.mpc(horizon)
                print(f"  built in {side.build_time[horizon]:.1f} s", flush=True)
        for rnd in range(args.rounds):
            order = ("crocoddyl", "geosyn") if rnd % 2 == 0 else ("geosyn", "crocoddyl")
            for solver in order:
                if solver == "crocoddyl":
                    info = run_crocoddyl(
                        args.croc_python,
                        args.horizon,
                        args.scenario,
                        work,
                        f"r{rnd}",
                        model_check=mass if rnd == 0 else None,
                        threads=args.croc_threads,
                    )
                    if rnd == 0:
                        croc_info = {k: v for k, v in info.items() if k not in ("runs", "arrays")}
                        print("Crocoddyl side:", json.dumps(croc_info))
                        check_crocoddyl_side(croc_info)
                    for run in info["runs"]:
                        key = f"{run['scenario']}_N{run['horizon']}"
                        run["solve_time"] = info["arrays"][f"{key}_solve_time"]
                        run["iterations"] = info["arrays"][f"{key}_iterations"]
                        run["solve_cpu"] = info["arrays"][f"{key}_solve_cpu"]
                        results.setdefault(
                            ("crocoddyl", run["horizon"], run["scenario"]), []
                        ).append(run)
                elif side is not None:
                    for horizon in args.horizon:
                        for scenario in args.scenario:
                            run = run_geosyn(side, ref, scenario, horizon)
                            results.setdefault(("geosyn", horizon, scenario), []).append(run)
            print(f"round {rnd + 1}/{args.rounds} done", flush=True)
    print()
    built = next(iter(side.mpcs.values()), None) if side is not None else None
    default = built.solver_options.name if built is not None else "default"  # type: ignore[attr-defined]
    solver, control = (
        str(options.get(k, d)) for k, d in (("solver", default), ("control", "torque"))
    )
    print(table(results, croc_info.get("crocoddyl", "?"), solver, control))
    for (who, horizon, scenario), runs in sorted(results.items()):
        if who == "geosyn":
            ticks = max(int(r.get("ticks_at_limit", 0)) for r in runs)
            viol = max(int(r["joint_limit_violations"]) for r in runs)
            excess = max(float(r["max_joint_limit_excess"]) for r in runs)
            guard = max(int(r["guard_ticks"]) for r in runs)
            print(
                f"geosyn {runs[0]['solver']} N={horizon} {scenario}: command at a torque limit"
                f" on {ticks} ticks; joint-limit violations {viol} (max excess {excess:.2e});"
                f" guard changed the torque on {guard} ticks"
            )
    if side is not None:
        print(
            "geosyn build times [s]: "
            + ", ".join(f"N={n}: {t:.1f}" for n, t in sorted(side.build_time.items()))
        )
    if args.save is not None:
        out = {
            "crocoddyl": croc_info,
            "runs": [
                {
                    "solver": s,
                    **{
                        k: v
                        for k, v in r.items()
                        if k not in ("solve_time", "solve_cpu", "iterations")
                    },
                    "solve_time_ms": (1e3 * np.asarray(r["solve_time"])).round(4).tolist(),
                }
                for (s, _, _), runs in sorted(results.items())
                for r in runs
            ],
        }
        args.save.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
