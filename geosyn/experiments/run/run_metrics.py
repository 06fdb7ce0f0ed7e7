"""The standard metrics of a closed-loop run, computed the same way for every experiment kind.

`standard_metrics` reduces one run (a `geosyn.sim.SimResult`, or the per-run arrays an
experiment stores in ``results.npz``) to named scalars:

- ``ok``: 1 if the run completed, 0 if it diverged or its controller failed;
- ``rms_error`` [rad]: ``sqrt(mean(e**2))`` of the tracking error over ticks and joints;
- ``max_error`` [rad]: the largest tracking-error norm ``||q_ref - q||_2``;
- ``recovery_time`` [s]: the longest of the per-window recovery times below, and
  ``recovery_time_d{i}`` [s] that of disturbance ``i`` (its index in ``disturbances``);
- ``effort`` [N^2 m^2 s]: ``integral ||tau_applied||^2 dt``;
- ``mechanical_energy`` [J]: ``integral |tau_applied . v| dt``, the work the motors do
  counting braking as work too;
- ``saturations``: number of (tick, joint) pairs whose torque was clipped, and
  ``saturated_fraction`` their share of all pairs;
- ``fallbacks``: number of ticks on which the controller used its fallback;
- ``min_clearance`` [m]: the smallest signed distance of the robot's collision spheres to
  the obstacles (``inf`` without obstacles), at every tick;
- ``min_mesh_clearance`` [m]: the same for the robot file's own collision geometry
  (meshes, primitives), exact (coal), at ticks at most 0.005 rad apart
  (`geosyn.sim.mesh_clearance`); left out when not measured (a robot built in code: the
  run log says why);
- ``max_contact_force`` [N]: the largest total normal force of the robot-obstacle
  contacts (when the run logs ``contact_force``; 0 with visual-only obstacles);
- ``wall_time`` [s] of the run;
- floating-base robots standing on the floor (`geosyn.experiments.run.floating`):
  ``feet_slip`` [m], the largest horizontal displacement of a contact frame,
  ``feet_sink`` [m], its largest vertical displacement, and ``min_base_height`` [m]; their
  tracking error is taken on the group (``pinocchio.difference``, base twist [m, rad]).

A run that did not complete (``ok`` 0: diverged, stopped, its controller failed) has
every other metric NaN, counts included: a count up to the stop would read as clean.

Recovery, per disturbance window
--------------------------------
A disturbance with a time window (a push ``[start, start + duration]``, a wrench
``[start, stop]``, a payload change at ``time``) opens an *evaluation interval* at its
start. The interval ends at the earliest of: the start of the next windowed disturbance,
the end of the reference when the reference ends *moving* (a geodesic traversed at
constant speed steps to rest there, which disturbs the tracking by itself), and the end
of the run. With ``e(t) = ||q_ref(t) - q(t)||_2`` and threshold ``h``:

- recovery is 0 when ``e <= h`` on every tick of the interval;
- otherwise, with ``k`` the last tick of the interval where ``e > h``, recovery is
  ``t[k + 1] - start``: the time from the disturbance's start until the error is back
  below ``h`` for the rest of the interval;
- recovery is ``inf`` when ``e > h`` on the interval's last tick (not recovered before the
  interval closed).

The end of the reference is found from the logged reference itself: the last tick on
which ``q_ref`` still changes. It counts as the end of a *moving* reference when the
reference speed there, ``||dq_ref/dt||``, exceeds ``REST_SPEED``. A rest-to-rest reference
(``rest_to_rest: true``) ends at rest and does not close an interval.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np

from geosyn.sim.blocks import row_blocks

#: Default error threshold of the recovery time [rad] (a procedure's ``threshold`` wins).
DEFAULT_THRESHOLD = 1e-2
#: Per-tick change of the reference below which it counts as held [rad] (the spline's
#: last sample and the held goal differ by rounding).
STILL = 1e-12
#: Reference speed above which the reference's end counts as a velocity step [rad/s].
REST_SPEED = 1e-3

#: Unit of each standard metric (the name after the last dot of a summary key).
UNITS: dict[str, str] = {
    "rms_error": "rad",
    "max_error": "rad",
    "recovery_time": "s",
    "effort": "N^2 m^2 s",
    "mechanical_energy": "J",
    "saturations": "count",
    "saturated_fraction": "1",
    "fallbacks": "count",
    "min_clearance": "m",
    "min_mesh_clearance": "m",
    "max_contact_force": "N",
    "wall_time": "s",
    "feet_slip": "m",
    "feet_sink": "m",
    "min_base_height": "m",
}


class Window(NamedTuple):
    """A disturbance's time window.

    Attributes:
        disturbance: the disturbance's index in the config's ``disturbances``.
        kind: its ``type`` (``push``, ``wrench``, ``payload_change``).
        start: when it starts acting [s].
        stop: when it stops acting [s] (``start`` for an instantaneous change).
    """

    disturbance: int
    kind: str
    start: float
    stop: float


def disturbance_windows(disturbances: Sequence[Any]) -> list[Window]:
    """The windows of the windowed disturbances among config sections ``disturbances``.

    Noise and latency act throughout the run and open no window. A wrench with
    ``stop: null`` has ``stop = inf``.
    """
    out = []
    for i, d in enumerate(disturbances):
        if d.type == "push":
            out.append(Window(i, "push", float(d.start), float(d.start + d.duration)))
        elif d.type == "wrench":
            stop = float("inf") if d.stop is None else float(d.stop)
            out.append(Window(i, "wrench", float(d.start), stop))
        elif d.type == "payload_change":
            out.append(Window(i, "payload_change", float(d.time), float(d.time)))
    return sorted(out, key=lambda w: w.start)


def reference_end(t: np.ndarray, q_ref: np.ndarray) -> tuple[float, float]:
    """(time [s], speed [rad/s]) at which the logged reference stops changing.

    Args:
        t: (T,) tick times [s].
        q_ref: (T, n) reference positions [rad] (NaN rows: no reference).

    Returns:
        The time of the first tick after the last change of ``q_ref`` (by more than
        `STILL`) and the reference
        speed ``||q_ref[k] - q_ref[k-1]|| / dt`` just before it; ``(inf, 0)`` when the
        reference still moves on the last tick or there is none.
    """
    n = len(t)
    if n < 2:
        return float("inf"), 0.0
    last, last_step = -1, 0.0  # the last step q_ref[i + 1] - q_ref[i] longer than STILL
    prev = None
    for rows in row_blocks(n, q_ref):  # a spooled log a block at a time
        block = np.asarray(q_ref[rows])
        if not np.all(np.isfinite(block)):
            return float("inf"), 0.0
        joined = block if prev is None else np.concatenate([prev, block])
        step = np.linalg.norm(np.diff(joined, axis=0), axis=1)
        moving = np.nonzero(step > STILL)[0]
        if moving.size:
            i = int(moving[-1])
            last, last_step = rows.start - (prev is not None) + i, float(step[i])
        prev = block[-1:]
    if last < 0:
        return float(t[0]), 0.0
    k = last + 1  # the first tick of the held goal
    if k >= n - 1:
        return float("inf"), 0.0
    return float(t[k]), float(last_step / (t[k] - t[k - 1]))


def recovery_times(
    t: np.ndarray,
    err_norm: np.ndarray,
    windows: Sequence[Window],
    threshold: float,
    reference_stop: float = float("inf"),
) -> list[float]:
    """Recovery time [s] of each window (the module doc gives the definition).

    Args:
        t: (T,) tick times [s].
        err_norm: (T,) tracking-error norm [rad].
        windows: the disturbance windows, sorted by start.
        threshold: the error threshold [rad].
        reference_stop: end of a reference that ends moving [s] (``inf``: none).

    Returns:
        One recovery time per window [s]: 0, a finite time, or ``inf``.
    """
    out = []
    starts = [w.start for w in windows]
    for i, w in enumerate(windows):
        close = min([s for s in starts[i + 1 :] if s > w.start] + [float("inf")])
        if reference_stop > w.start:
            close = min(close, reference_stop)
        idx = np.nonzero((t >= w.start) & (t < close))[0]
        if idx.size == 0:
            out.append(float("nan"))  # the window starts after the run ended
            continue
        above = idx[err_norm[idx] > threshold]
        if above.size == 0:
            out.append(0.0)
        elif above[-1] == idx[-1]:
            out.append(float("inf"))
        else:
            out.append(float(t[above[-1] + 1] - w.start))
    return out


def _array(run: Any, name: str) -> np.ndarray | None:
    value = run.get(name) if isinstance(run, Mapping) else getattr(run, name, None)
    return None if value is None else np.asarray(value)


def standard_metrics(
    run: Any,
    control_dt: float,
    windows: Sequence[Window] = (),
    threshold: float = DEFAULT_THRESHOLD,
) -> dict[str, float]:
    """The standard metrics of one run (see the module doc).

    Args:
        run: a `geosyn.sim.SimResult`, or a mapping of its arrays by field name (what
            `geosyn.experiments.run.build.sim_view` gives for a stored run).
        control_dt: control period [s].
        windows: the disturbance windows (`disturbance_windows`).
        threshold: error threshold of the recovery times [rad].

    Returns:
        metric name -> value (``recovery_time*`` only with windows; metrics whose arrays
        the run lacks are left out).
    """
    t = np.asarray(_array(run, "t"), dtype=np.float64)
    e = _array(run, "tracking_error")
    tau = _array(run, "tau_applied")
    v = _array(run, "v")
    status = _array(run, "status")
    sat = _array(run, "saturated")
    fb = _array(run, "fallback_used")
    contact = _array(run, "contact_force")
    clearance = _array(run, "clearance")
    out: dict[str, float] = {}
    if status is not None:
        out["ok"] = float(str(status) == "ok")
    sums = _block_sums(len(t), e, tau, v, sat, fb, contact, clearance)
    if e is not None and len(t) and sums["e_finite"]:
        out["rms_error"] = float(np.sqrt(sums["e_squares"] / e.size))
        out["max_error"] = sums["e_max_norm"]
        if windows:
            norm = np.empty(len(t))
            for rows in row_blocks(len(t), e):
                norm[rows] = np.linalg.norm(e[rows], axis=1)
            q_ref = _array(run, "q_ref")
            stop, speed = reference_end(t, q_ref) if q_ref is not None else (float("inf"), 0.0)
            reference_stop = stop if speed > REST_SPEED else float("inf")
            times = recovery_times(t, norm, windows, threshold, reference_stop)
            finite = [x for x in times if not np.isnan(x)]
            out["recovery_time"] = max(finite) if finite else float("nan")
            for w, rt in zip(windows, times, strict=True):
                out[f"recovery_time_d{w.disturbance}"] = rt
    if tau is not None:
        out["effort"] = float(sums["tau_squares"] * control_dt)
        if v is not None:
            out["mechanical_energy"] = float(sums["abs_power"] * control_dt)
    if sat is not None:
        out["saturations"] = float(sums["saturations"])
        out["saturated_fraction"] = float(sums["saturations"] / sat.size) if sat.size else 0.0
    if fb is not None:
        out["fallbacks"] = float(sums["fallbacks"])
    if contact is not None and contact.size and sums["contact_finite"]:
        out["max_contact_force"] = sums["max_contact"]
    if clearance is not None and clearance.size:
        out["min_clearance"] = sums["min_clearance"]
    mesh = _array(run, "mesh_clearance")
    if mesh is not None and not np.isnan(mesh):  # NaN: not measured (the run log says why)
        out["min_mesh_clearance"] = float(mesh)
    for name in ("feet_slip", "feet_sink", "min_base_height"):  # floating robots only
        value = _array(run, name)
        if value is not None:
            out[name] = float(value)
    wall = _array(run, "wall_time")
    if wall is not None:
        out["wall_time"] = float(wall)
    if status is not None and str(status) != "ok":
        return _not_measured(out, e is not None, windows)
    return out


def _block_sums(n: int, *arrays: np.ndarray | None) -> dict[str, Any]:
    """The sums, extremes and counts `standard_metrics` reports, over the ``n`` ticks of
    ``(tracking_error, tau_applied, v, saturated, fallback_used, contact_force,
    clearance)`` (each may be None), a block of ticks at a time: a spooled log's pages
    are released after each block (`geosyn.sim.blocks.row_blocks`). A run of at most one
    block is reduced as a whole, so its numbers are numpy's own of the whole arrays."""
    e, tau, v, sat, fb, contact, clearance = arrays
    out: dict[str, Any] = {"e_finite": True, "e_squares": 0.0, "e_max_norm": 0.0}
    out |= {"tau_squares": 0.0, "abs_power": 0.0, "saturations": 0, "fallbacks": 0}
    out |= {"contact_finite": True, "max_contact": -np.inf, "min_clearance": np.inf}
    present = [a for a in arrays if a is not None]
    for rows in row_blocks(n, *present):
        if e is not None and out["e_finite"]:
            eb = e[rows]
            out["e_finite"] = bool(np.all(np.isfinite(eb)))
            out["e_squares"] += np.sum(eb**2)
            if len(eb):
                out["e_max_norm"] = max(out["e_max_norm"], float(np.linalg.norm(eb, axis=1).max()))
        if tau is not None:
            tb = tau[rows]
            out["tau_squares"] += np.sum(tb**2)
            if v is not None:
                out["abs_power"] += np.sum(np.abs(np.einsum("ij,ij->i", tb, v[rows])))
        if sat is not None:
            out["saturations"] += int(np.count_nonzero(sat[rows]))
        if fb is not None:
            out["fallbacks"] += int(np.count_nonzero(fb[rows]))
        if contact is not None and len(contact[rows]):
            cb = contact[rows]
            out["contact_finite"] &= bool(np.all(np.isfinite(cb)))
            out["max_contact"] = max(out["max_contact"], float(np.max(cb)))
        if clearance is not None and len(clearance[rows]):
            low = np.min(clearance[rows])  # np.min: a NaN clearance stays NaN
            out["min_clearance"] = float(np.min((out["min_clearance"], low)))
    return out


def _not_measured(
    out: dict[str, float], tracked: bool, windows: Sequence[Window]
) -> dict[str, float]:
    """The metrics of a run that did not complete: all NaN (counts included: a count up
    to the stop would read as a clean run), except ``ok`` and ``wall_time``; the
    tracking metrics are present (as NaN) even when the error went non-finite."""
    names = set(out)
    if tracked:
        names |= {"rms_error", "max_error"}
        if windows:
            names |= {"recovery_time", *(f"recovery_time_d{w.disturbance}" for w in windows)}
    return {
        name: out[name] if name in ("ok", "wall_time") else float("nan") for name in sorted(names)
    }


def unit_of(metric: str) -> str:
    """Unit of a standard metric name (``recovery_time_d3`` -> ``s``); ``""`` if unknown."""
    if metric.startswith("recovery_time"):
        return "s"
    return UNITS.get(metric, "")


__all__ = [
    "DEFAULT_THRESHOLD",
    "REST_SPEED",
    "UNITS",
    "Window",
    "disturbance_windows",
    "recovery_times",
    "reference_end",
    "standard_metrics",
    "unit_of",
]
