"""The per-tick log of a simulation run: `SimResult`, saved to and loaded from ``.npz``.

Row ``k`` describes control tick ``k``: the true state at ``t[k]`` (before the tick's
torque acts), what the controller measured and commanded, what was applied during
``[t[k], t[k] + control_dt)``, and derived quantities at ``t[k]``. A run that stopped early
(divergence, controller failure) has only the rows of the ticks that ran.

`LOG_FIELDS` is the one declaration of the logged arrays (name, shape, unit, dtype, how
they are filled): the simulation allocates its per-tick buffers from it (`allocate_rows`),
`finish_rows` adds the derived arrays, and `SimResult.save`/`SimResult.load` write and
read exactly these arrays.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.sim.blocks import mapping_of, row_blocks, save_npz


class LogField(NamedTuple):
    """One logged array of a `SimResult`.

    Attributes:
        name: attribute of `SimResult` and key in the saved ``.npz``.
        shape: dimension names: ``T`` ticks, ``nq``, ``nv``, ``P`` payloads.
        unit: SI unit; ``""`` for flags, counts and codes.
        source: ``"tick"`` (written by the simulation at each tick), ``"derived"``
            (computed from the tick rows by `finish_rows`) or ``"final"`` (the state after
            the last tick).
        dtype: numpy dtype of the array.
        fill: value of a row the simulation does not write (e.g. no reference: NaN).
    """

    name: str
    shape: tuple[str, ...]
    unit: str
    source: str = "tick"
    dtype: type = np.float64
    fill: float = 0.0


#: Every array of a `SimResult`, in the order of its attributes.
LOG_FIELDS: tuple[LogField, ...] = (
    LogField("t", ("T",), "s"),
    LogField("q", ("T", "nq"), "rad"),
    LogField("v", ("T", "nv"), "rad/s"),
    LogField("q_meas", ("T", "nq"), "rad"),
    LogField("v_meas", ("T", "nv"), "rad/s"),
    LogField("tau", ("T", "nv"), "N m"),
    LogField("tau_applied", ("T", "nv"), "N m"),
    LogField("q_ref", ("T", "nq"), "rad", fill=np.nan),
    LogField("v_ref", ("T", "nv"), "rad/s", fill=np.nan),
    LogField("tracking_error", ("T", "nq"), "rad", "derived"),
    LogField("kinetic_energy", ("T",), "J"),
    LogField("power", ("T",), "W", "derived"),
    LogField("effort", ("T",), "N^2 m^2 s", "derived"),
    LogField("saturated", ("T", "nv"), "", dtype=np.bool_),
    LogField("clearance", ("T",), "m", fill=np.inf),
    LogField("contact_force", ("T",), "N", fill=0.0),
    LogField("payload_mass", ("T", "P"), "kg"),
    LogField("compute_time", ("T",), "s"),
    LogField("iterations", ("T",), "", dtype=np.int64, fill=-1),
    LogField("fallback_used", ("T",), "", dtype=np.bool_),
    LogField("solver_status", ("T",), "", dtype=np.int64),
    LogField("q_final", ("nq",), "rad", "final"),
    LogField("v_final", ("nv",), "rad/s", "final"),
)

#: Names of the arrays of a `SimResult`, in order.
ARRAY_FIELDS = tuple(f.name for f in LOG_FIELDS)


def allocate_rows(n_ticks: int, dims: Mapping[str, int]) -> dict[str, np.ndarray]:
    """Buffers for the ``"tick"`` fields of `LOG_FIELDS`, each filled with its ``fill``.

    Args:
        n_ticks: number of ticks planned (the ``T`` dimension).
        dims: sizes of the other dimensions: ``nq``, ``nv``, ``P``.

    Returns:
        ``{name: (n_ticks, ...) array}``; the simulation writes row ``k`` at tick ``k``.
    """
    sizes = {"T": n_ticks, **dims}
    return {
        f.name: np.full(tuple(sizes[d] for d in f.shape), f.fill, dtype=f.dtype)
        for f in LOG_FIELDS
        if f.source == "tick"
    }


def finish_rows(rows: Mapping[str, np.ndarray], done: int, control_dt: float) -> dict[str, Any]:
    """The tick rows that ran, plus the ``"derived"`` fields computed from them.

    Args:
        rows: buffers from `allocate_rows`, rows ``0 .. done-1`` written.
        done: number of ticks that ran.
        control_dt: control period [s] (the effort integrates over it).

    Returns:
        ``{name: (done, ...) array}`` for every ``"tick"`` and ``"derived"`` field.
    """
    out: dict[str, Any] = {name: (a[:done] if done < len(a) else a) for name, a in rows.items()}
    derived, _ = derive_rows(out, control_dt)
    return out | derived


def derive_rows(
    rows: Mapping[str, np.ndarray], control_dt: float, effort_sum: float = 0.0
) -> tuple[dict[str, np.ndarray], float]:
    """The ``"derived"`` fields of consecutive tick rows (a whole run, or one chunk of it).

    Row by row, so a run derived chunk by chunk (`geosyn.sim.log_spool`) gives the same
    bits as derived whole: the effort's running sum is carried over from chunk to chunk
    and accumulated in the same order.

    Args:
        rows: ``(n, ...)`` ``q``, ``q_ref``, ``v``, ``tau_applied`` of ``n`` ticks.
        control_dt: control period [s].
        effort_sum: ``sum ||tau_applied||^2`` of the ticks before these [N^2 m^2].

    Returns:
        (``{name: (n, ...) array}`` of the derived fields, the running sum after them).
    """
    tau, v = rows["tau_applied"], rows["v"]
    squares = np.einsum("ij,ij->i", tau, tau)
    if len(squares):
        squares[0] += effort_sum
    total = np.cumsum(squares)
    out = {
        "tracking_error": rows["q_ref"] - rows["q"],
        "power": np.einsum("ij,ij->i", tau, v),
        "effort": total * control_dt,
    }
    return out, float(total[-1]) if len(total) else effort_sum


@dataclass(frozen=True, eq=False)
class SimResult:
    """Per-tick log of one run (T ticks; T < planned when the run stopped early).

    A run of more than ``SPOOL_CHUNK`` ticks was written to disk in chunks as it ran
    (`geosyn.sim.log_spool`): its per-tick arrays are read-only memory maps of that file
    (`spooled`), whose disk space the system frees when the last of them is garbage
    collected (the file itself was removed when the run ended). Consumers that scan a
    whole log do it a block at a time (`geosyn.sim.blocks`), so memory stays bounded.

    Attributes:
        t: (T,) time of each control tick [s].
        q: (T, nq) true joint positions [rad].
        v: (T, nv) true joint velocities [rad/s].
        q_meas: (T, nq) positions the controller received (after noise and latency) [rad].
        v_meas: (T, nv) velocities the controller received [rad/s].
        tau: (T, nv) controller command clipped to the torque limits [N m].
        tau_applied: (T, nv) torque sent to the motors: command after torque disturbances,
            clipped [N m]; held during the tick.
        q_ref: (T, nq) reference positions [rad]; NaN without a reference.
        v_ref: (T, nv) reference velocities [rad/s]; NaN without a reference.
        tracking_error: (T, nq) ``q_ref - q`` [rad].
        kinetic_energy: (T,) 1/2 v^T M(q) v of the simulated plant, payloads included [J].
        power: (T,) mechanical power of the motors ``tau_applied . v`` [W].
        effort: (T,) cumulative effort: integral of ``||tau_applied||^2`` up to the end of
            tick k [N^2 m^2 s].
        saturated: (T, nv) the torque on that joint was clipped at its limit, by the
            simulation or by the controller itself (its ``diagnostics.saturated``).
        clearance: (T,) minimum signed distance robot collision spheres to obstacles [m];
            ``inf`` without obstacles.
        contact_force: (T,) sum of the normal forces of the robot-obstacle contacts at the
            tick [N]; 0 when obstacles are visual only (``contact=False``).
        payload_mass: (T, P) mass of each payload during the tick [kg].
        compute_time: (T,) wall time of the controller's ``compute`` [s].
        iterations: (T,) solver iterations reported by the controller (-1: not reported).
        fallback_used: (T,) the controller reported using its fallback.
        solver_status: (T,) code of the controller's solver status; the name of code i is
            ``solver_status_names[i]`` (code 0: none reported).
        q_final: (nq,) true state at the end of the last tick [rad].
        v_final: (nv,) [rad/s].
        solver_status_names: names of the solver-status codes.
        joint_names: (nv,) joint names.
        robot_name: name of the robot.
        control_dt: control period [s].
        substeps: physics steps per control tick.
        integrator: MuJoCo integrator.
        duration: planned duration [s].
        status: ``"ok"``, ``"diverged: ..."`` or ``"controller failed: ..."``.
        wall_time: wall time of the run [s].
        seed: the seed of the run's random generators.
        controller_notes: the controller's ``diagnostics.notes`` at the end of the run,
            ``"name: text"`` each (what it changed, modelled or guarded; () if none).
        mesh_clearance: smallest exact clearance [m] of the robot file's collision
            geometry to the obstacles over the run (`geosyn.sim.mesh_clearance`; negative:
            penetration); NaN when not measured (no obstacles, no file geometry).
        mesh_clearance_note: how ``mesh_clearance`` was measured, or why not.
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    q_meas: np.ndarray
    v_meas: np.ndarray
    tau: np.ndarray
    tau_applied: np.ndarray
    q_ref: np.ndarray
    v_ref: np.ndarray
    tracking_error: np.ndarray
    kinetic_energy: np.ndarray
    power: np.ndarray
    effort: np.ndarray
    saturated: np.ndarray
    clearance: np.ndarray
    contact_force: np.ndarray
    payload_mass: np.ndarray
    compute_time: np.ndarray
    iterations: np.ndarray
    fallback_used: np.ndarray
    solver_status: np.ndarray
    q_final: np.ndarray
    v_final: np.ndarray
    solver_status_names: tuple[str, ...]
    joint_names: tuple[str, ...]
    robot_name: str
    control_dt: float
    substeps: int
    integrator: str
    duration: float
    status: str
    wall_time: float
    seed: int
    controller_notes: tuple[str, ...] = ()
    mesh_clearance: float = math.nan
    mesh_clearance_note: str = ""

    # -- summaries --------------------------------------------------------------------
    @property
    def n_ticks(self) -> int:
        """Number of ticks that ran."""
        return int(len(self.t))

    @property
    def ok(self) -> bool:
        """Whether the run completed without divergence or failure."""
        return self.status == "ok"

    @property
    def diverged(self) -> bool:
        """Whether the run stopped on a divergence."""
        return self.status.startswith("diverged")

    @property
    def real_time_factor(self) -> float:
        """Simulated time per wall time (> 1: faster than real time)."""
        return (
            float(self.n_ticks * self.control_dt / self.wall_time)
            if self.wall_time > 0
            else float("inf")
        )

    @property
    def total_effort(self) -> float:
        """Integral of ``||tau_applied||^2`` over the run [N^2 m^2 s]."""
        return float(self.effort[-1]) if self.n_ticks else 0.0

    def rms_error(self, t_from: float = 0.0, t_to: float = float("inf")) -> float:
        """RMS tracking error over ticks with ``t_from <= t < t_to`` [rad] (NaN if none).

        The mean is over ticks and joints: ``sqrt(mean(tracking_error**2))``; computed
        a block of ticks at a time (`geosyn.sim.blocks.row_blocks`), O(T).
        """
        t, err = self.t, self.tracking_error
        total, count = 0.0, 0
        for rows in row_blocks(len(t), t, err):
            sel = (t[rows] >= t_from) & (t[rows] < t_to)
            if np.any(sel):
                picked = err[rows][sel]
                total += float(np.sum(picked**2))
                count += picked.size
        if not count:
            return float("nan")
        return float(np.sqrt(total / count))

    def saturation_count(self) -> int:
        """Number of (tick, joint) pairs whose torque was clipped (a block at a time)."""
        sat = self.saturated
        return sum(int(np.count_nonzero(sat[rows])) for rows in row_blocks(len(sat), sat))

    @property
    def spooled(self) -> bool:
        """Whether the per-tick arrays are read-only maps of a spool file on disk
        (`geosyn.sim.log_spool`: runs longer than ``SPOOL_CHUNK`` ticks), not in memory."""
        return mapping_of(self.t) is not None

    # -- persistence ------------------------------------------------------------------
    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the log to a compressed ``.npz`` file (suffix added if missing).

        A spooled log is written a block of ticks at a time (`geosyn.sim.blocks.save_npz`).

        Returns:
            The path written.
        """
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_name(path.name + ".npz")
        arrays: dict[str, Any] = {name: np.asarray(getattr(self, name)) for name in ARRAY_FIELDS}
        return save_npz(path, {"__meta__": np.array(self.metadata_json()), **arrays})

    def metadata_json(self) -> str:
        """The non-array attributes as JSON (what `load` needs besides the arrays)."""
        meta = {f.name: getattr(self, f.name) for f in fields(self) if f.name not in ARRAY_FIELDS}
        meta["solver_status_names"] = list(meta["solver_status_names"])
        meta["joint_names"] = list(meta["joint_names"])
        meta["controller_notes"] = list(meta["controller_notes"])
        return json.dumps(meta)

    @classmethod
    def load(cls, path: str | os.PathLike[str], run: str | None = None) -> SimResult:
        """Read a log written by `save`, or one run of an experiment's ``results.npz``.

        An experiment stores each closed-loop run under a prefix (its controller label,
        or ``{path}_{label}``; see `geosyn.experiments.run.build.sim_arrays`) with its
        metadata; `saved_runs` lists them. The arrays an experiment does not keep
        (``q_meas``, ``v_meas``, ``tau``, ``v_ref``, ``compute_time``, ``q_final``,
        ``v_final``) are NaN, ``iterations`` -1 and ``solver_status`` 0 (none reported).

        Args:
            path: the ``.npz`` file.
            run: the run's prefix in an experiment's file; None: the file's only run.

        Raises:
            InvalidArgument: the file is missing, is not a saved `SimResult` or
                experiment, or ``run`` is not one of its runs (the message lists them).
        """
        path = Path(path)
        if not path.is_file():
            raise InvalidArgument(f"path {str(path)!r} is not a file")
        try:
            with np.load(path, allow_pickle=False) as data:
                if "__meta__" in data.files and run is None:
                    meta = json.loads(str(data["__meta__"]))
                    arrays: dict[str, Any] = {n: np.array(data[n]) for n in ARRAY_FIELDS}
                else:
                    meta, arrays = _experiment_run(path, data, run)
        except InvalidArgument:
            raise
        except (KeyError, ValueError, OSError) as err:
            raise InvalidArgument(f"path {str(path)!r} is not a saved SimResult: {err}") from err
        meta["solver_status_names"] = tuple(meta["solver_status_names"])
        meta["joint_names"] = tuple(meta["joint_names"])
        meta["controller_notes"] = tuple(meta.get("controller_notes", ()))  # older files: none
        return cls(**arrays, **meta)


#: Suffix of a run's metadata key in an experiment's ``results.npz``.
RUN_META = "__meta"


def saved_runs(path: str | os.PathLike[str]) -> list[str]:
    """Prefixes of the runs stored in an experiment's ``results.npz`` (storage order)."""
    with np.load(Path(path), allow_pickle=False) as data:
        return [k[: -len(RUN_META)] for k in data.files if k.endswith(RUN_META) and k != "__meta__"]


def _experiment_run(
    path: Path, data: Any, run: str | None
) -> tuple[dict[str, Any], dict[str, Any]]:
    """(metadata, arrays) of run ``run`` of an experiment's npz; absent arrays filled."""
    runs = [k[: -len(RUN_META)] for k in data.files if k.endswith(RUN_META) and k != "__meta__"]
    if run is None and len(runs) == 1:
        run = runs[0]
    if run not in runs:
        what = "which run" if run is None else f"run {run!r} is not in it"
        listed = ", ".join(runs) or "none with metadata (written before geosyn stored it)"
        raise InvalidArgument(f"path {str(path)!r}: {what}? runs: {listed}")
    meta = json.loads(str(data[f"{run}{RUN_META}"]))
    q, v = data[f"{run}__q"], data[f"{run}__v"]
    dims = {"T": q.shape[0], "nq": q.shape[1], "nv": v.shape[1], "P": 0}
    arrays: dict[str, Any] = {}
    for f in LOG_FIELDS:
        key = f"{run}__{f.name}"
        if key in data.files:
            arrays[f.name] = np.array(data[key])
        else:  # not kept by the experiment: NaN for measurements, the fill for codes
            fill = np.nan if f.dtype is np.float64 else f.fill
            arrays[f.name] = np.full(tuple(dims[d] for d in f.shape), fill, dtype=f.dtype)
    return meta, arrays


__all__ = [
    "ARRAY_FIELDS",
    "LOG_FIELDS",
    "RUN_META",
    "LogField",
    "SimResult",
    "allocate_rows",
    "derive_rows",
    "finish_rows",
    "saved_runs",
]
