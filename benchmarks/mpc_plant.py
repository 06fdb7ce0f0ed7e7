"""The plant and the Panda model shared by both sides of ``benchmarks/mpc_vs_crocoddyl.py``.

Imports only numpy and pinocchio, so that geosyn's venv and the Crocoddyl venv
(``.venv-croc``, see ``benchmarks/setup_crocoddyl.sh``) run the very same code:

- `panda_model`: geosyn's built-in ``"panda"`` rebuilt from the example-robot-data URDF
  the way geosyn's ``load_robot("panda")`` builds it (arm joints kept, fingers locked at 0,
  armature 0.1 kg m^2 per joint, gravity -9.81 m/s^2 along z). The benchmark checks M(q)
  of both sides against each other through an .npz file.
- `ReferenceSamples`: the geodesic reference at 1 kHz, read from the .npz file, with
  exact lookups on the 1 kHz grid.
- `run_closed_loop`: the 1 kHz closed loop, ``pin.aba`` + RK4 with the commanded torque
  held over the tick and saturated at the torque limits (an actuator cannot exceed them;
  the commanded torque is recorded before saturation, to count limit violations).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pinocchio as pin

TICK = 1e-3  # plant step and control period [s]
MPC_DT = 0.02  # MPC stage length and re-solve period [s]
PANDA_ARMATURE = 0.1  # reflected rotor inertia per joint [kg m^2], geosyn's default
GRAVITY = (0.0, 0.0, -9.81)  # [m/s^2]
ARM_JOINTS = tuple(f"panda_joint{i}" for i in range(1, 8))
DURATION = 1.5  # closed-loop run, the tracked part of the reference [s]
SCENARIOS = ("on_reference", "offset_at_rest")
OFFSET = 0.1  # initial offset of every joint in "offset_at_rest" [rad]


def panda_urdf() -> Path:
    """The Panda URDF of the example-robot-data package installed next to pinocchio."""
    for base in Path(pin.__file__).resolve().parents:
        cand = (
            base / "cmeel.prefix/share/example-robot-data/robots/panda_description/urdf/panda.urdf"
        )
        if cand.is_file():
            return cand
    raise FileNotFoundError("example-robot-data is not installed next to pinocchio")


def panda_model(armature: float = PANDA_ARMATURE) -> pin.Model:
    """geosyn's ``load_robot("panda")`` model: 7 arm joints, fingers locked at 0.

    Same steps as geosyn's ``robot_from_model``: every joint but the arm's is
    locked at 0 clipped into its limits, gravity set, armature ``armature`` [kg m^2] on
    each joint (the URDF's effort and velocity limits are all positive, so geosyn's
    defaults for missing limits do not apply).
    """
    full = pin.buildModelFromUrdf(str(panda_urdf()))
    q_lock = pin.neutral(full)
    to_lock = []
    for jid in range(1, full.njoints):
        if full.names[jid] in ARM_JOINTS:
            continue
        to_lock.append(jid)
        iq = full.joints[jid].idx_q
        lo, hi = full.lowerPositionLimit[iq], full.upperPositionLimit[iq]
        q_lock[iq] = float(np.clip(0.0, lo, hi)) if lo <= hi else 0.0
    model = pin.buildReducedModel(full, to_lock, q_lock)
    if tuple(model.names[1:]) != ARM_JOINTS:
        raise RuntimeError(f"unexpected Panda joints {list(model.names[1:])}")
    model.gravity = pin.Motion(np.array(GRAVITY), np.zeros(3))
    model.armature = np.full(model.nv, float(armature))
    return model


class ReferenceSamples(NamedTuple):
    """A joint trajectory sampled every `TICK` from ``t[0] = 0``.

    Attributes:
        t: (T,) time stamps [s].
        q: (T, n) joint positions [rad].
        v: (T, n) joint velocities [rad/s].
        a: (T, n) joint accelerations [rad/s^2].
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray

    @classmethod
    def load(cls, path: str | Path) -> ReferenceSamples:
        with np.load(path) as f:
            return cls(*(np.array(f[k], dtype=np.float64) for k in ("t", "q", "v", "a")))

    def index(self, t: float) -> int:
        """Grid index of time ``t`` [s]; ``t`` must lie on the 1 kHz grid, inside the samples."""
        i = int(round(t / TICK))
        if abs(i * TICK - t) > 1e-9 or not 0 <= i < self.t.size:
            raise ValueError(
                f"t={t!r} is not a sample time of the reference (grid {TICK} s, "
                f"0..{self.t[-1]:.3f} s); lengthen the reference or shorten the horizon"
            )
        return i

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, v, a) at sample time ``t`` [s] (views)."""
        i = self.index(t)
        return self.q[i], self.v[i], self.a[i]


def initial_state(scenario: str, ref: ReferenceSamples) -> tuple[np.ndarray, np.ndarray]:
    """(q0, v0) of a scenario: on the reference, or `OFFSET` off on every joint at rest."""
    if scenario == "on_reference":
        return ref.q[0].copy(), ref.v[0].copy()
    if scenario == "offset_at_rest":
        return ref.q[0] + OFFSET, np.zeros_like(ref.v[0])
    raise ValueError(f"scenario {scenario!r} unknown; allowed: {', '.join(SCENARIOS)}")


def rk4_step(
    model: pin.Model, data: pin.Data, q: np.ndarray, v: np.ndarray, tau: np.ndarray, h: float
) -> tuple[np.ndarray, np.ndarray]:
    """One RK4 step of ``qdd = aba(q, v, tau)`` with ``tau`` held constant (nq == nv)."""

    def acc(qq: np.ndarray, vv: np.ndarray) -> np.ndarray:
        return pin.aba(model, data, qq, vv, tau).copy()

    a1 = acc(q, v)
    q2, v2 = q + 0.5 * h * v, v + 0.5 * h * a1
    a2 = acc(q2, v2)
    q3, v3 = q + 0.5 * h * v2, v + 0.5 * h * a2
    a3 = acc(q3, v3)
    q4, v4 = q + h * v3, v + h * a3
    a4 = acc(q4, v4)
    q_next = q + (h / 6.0) * (v + 2.0 * v2 + 2.0 * v3 + v4)
    v_next = v + (h / 6.0) * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
    return q_next, v_next


class Rollout(NamedTuple):
    """A closed-loop run.

    Attributes:
        t: (K+1,) time stamps [s].
        q: (K+1, n) joint positions [rad].
        v: (K+1, n) joint velocities [rad/s].
        tau_cmd: (K, n) commanded torques, before the actuator saturation [N m].
        solve_ticks: (S,) indices of the ticks at which the controller re-solved.
        solve_time: (S,) wall time of those ticks' controller calls [s].
        solve_cpu: (S,) CPU time of this process in those calls [s] (less sensitive to
            other load on the machine than the wall time; equal to it when idle and
            single-threaded).
        iterations: (S,) solver iterations of each solve.
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    tau_cmd: np.ndarray
    solve_ticks: np.ndarray
    solve_time: np.ndarray
    solve_cpu: np.ndarray
    iterations: np.ndarray


#: A controller for `run_closed_loop`: ``(k, t, q, v) -> (tau_cmd, iterations)``; it
#: re-solves when ``k`` is a multiple of ``MPC_DT / TICK`` (iterations -1 on other ticks).
Policy = Callable[[int, float, np.ndarray, np.ndarray], tuple[np.ndarray, int]]


def run_closed_loop(
    model: pin.Model, q0: np.ndarray, v0: np.ndarray, duration: float, policy: Policy
) -> Rollout:
    """Simulate ``duration`` [s] at 1 kHz; time the policy's calls on re-solve ticks."""
    ticks = int(round(duration / TICK))
    per_solve = int(round(MPC_DT / TICK))
    data = model.createData()
    tau_max = np.asarray(model.effortLimit, dtype=np.float64)
    n = model.nv
    qs, vs = np.empty((ticks + 1, n)), np.empty((ticks + 1, n))
    tau_cmd = np.empty((ticks, n))
    solve_ticks = np.arange(0, ticks, per_solve)
    solve_time = np.empty(solve_ticks.size)
    solve_cpu = np.empty(solve_ticks.size)
    iterations = np.empty(solve_ticks.size, dtype=int)
    q, v = np.array(q0, dtype=np.float64), np.array(v0, dtype=np.float64)
    qs[0], vs[0] = q, v
    for k in range(ticks):
        t = k * TICK
        start, cpu = time.perf_counter(), time.process_time()
        tau, iters = policy(k, t, q, v)
        elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu
        if k % per_solve == 0:
            solve_time[k // per_solve] = elapsed
            solve_cpu[k // per_solve] = cpu
            iterations[k // per_solve] = iters
        tau_cmd[k] = tau
        q, v = rk4_step(model, data, q, v, np.clip(tau, -tau_max, tau_max), TICK)
        qs[k + 1], vs[k + 1] = q, v
    t_all = np.arange(ticks + 1) * TICK
    return Rollout(t_all, qs, vs, tau_cmd, solve_ticks, solve_time, solve_cpu, iterations)


def tracking_rms(rollout: Rollout, ref: ReferenceSamples) -> float:
    """RMS joint position error against the reference over the run [rad]."""
    k = rollout.t.size
    return float(np.sqrt(np.mean((rollout.q - ref.q[:k]) ** 2)))


def limit_violations(
    tau_cmd: np.ndarray, tau_max: np.ndarray, tol: float = 1e-6
) -> tuple[int, float]:
    """Ticks with a commanded torque over its limit (by > ``tol`` N m), and the largest excess
    relative to the limit (0 when none)."""
    excess = np.abs(tau_cmd) - tau_max
    over = excess > tol
    return int(np.count_nonzero(over.any(axis=1))), float(max(0.0, (excess / tau_max).max()))
