"""Helpers shared by the procedures: parameter types, finite differences and the
geodesic residual, tracking runs of every configured controller, and `PathComparison`,
the base of the procedures that compare paths tracked in MuJoCo."""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, ClassVar

import numpy as np
from pydantic import Field

from geosyn.experiments.procedures.base import Procedure
from geosyn.experiments.results.plots import bar_plot, torque_plot, tracking_error_plot
from geosyn.experiments.run import build as B
from geosyn.experiments.run.scene import BuiltScene
from geosyn.experiments.schema import ExperimentConfig
from geosyn.metrics import Metric
from geosyn.robots import Robot
from geosyn.sim import SimResult

#: A duration of a procedure's parameters [s], > 0.
Duration = Annotated[float, Field(gt=0.0)]
#: A number of integration steps of a procedure's parameters.
Steps = Annotated[int, Field(ge=10, le=10_000)]
#: Axis label of the effort ``integral ||tau||^2 dt``.
EFFORT_LABEL = r"$\int \|\tau\|^2 dt$ [N$^2$m$^2$s]"


def robot_and_metric(cfg: ExperimentConfig) -> tuple[Robot, Metric]:
    """The config's robot and its metric, built anew (for plots, which get no context)."""
    robot = B.build_robot(cfg)
    return robot, B.build_metric(cfg, robot)


def fd_derivatives(t: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Velocity and acceleration of uniformly sampled positions, 4th-order central differences.

    Args:
        t: (T,) uniform time stamps [s], T >= 5.
        q: (T, n) positions [rad].

    Returns:
        (interior indices (T-4,), qd (T-4, n) [rad/s], qdd (T-4, n) [rad/s^2]); the
        truncation error is O(h^4) in the sample spacing h.
    """
    h = float(t[1] - t[0])
    qm2, qm1, q0, qp1, qp2 = q[:-4], q[1:-3], q[2:-2], q[3:-1], q[4:]
    qd = (-qp2 + 8.0 * qp1 - 8.0 * qm1 + qm2) / (12.0 * h)
    qdd = (-qp2 + 16.0 * qp1 - 30.0 * q0 + 16.0 * qm1 - qm2) / (12.0 * h * h)
    return np.arange(2, len(t) - 2), qd, qdd


def geodesic_residual(metric: Metric, t: np.ndarray, q: np.ndarray) -> float:
    """Largest violation of the geodesic equation along a sampled path.

    .. math:: r = \\max_k \\| G(q_k) \\ddot q_k + C(q_k, \\dot q_k) \\dot q_k \\|_2

    with ``qd``, ``qdd`` from 4th-order finite differences of the positions only (so a
    path is judged by its shape, not by the velocities an integrator reports). For the
    kinetic-energy metric ``r`` is a torque [N m]: the force needed, gravity aside, to
    keep the robot on the path. Along an RK4 geodesic with h = 1/400 s, r ~ 1e-8.
    """
    idx, qd, qdd = fd_derivatives(t, q)
    r = 0.0
    for i, k in enumerate(idx):
        res = metric.G(q[k]) @ qdd[i] + metric.coriolis(q[k], qd[i])
        r = max(r, float(np.linalg.norm(res)))
    return r


def track_with_each_controller(
    cfg: ExperimentConfig,
    scene: BuiltScene,
    metric: Metric,
    reference: Any,
    q0: np.ndarray,
    v0: np.ndarray,
    prefix: str,
    advance: Callable[[], None],
    duration: float | None = None,
    each: Callable[[str, SimResult], None] | None = None,
) -> dict[str, np.ndarray]:
    """Simulate every configured controller tracking ``reference`` from ``(q0, v0)``.

    Args:
        cfg: the experiment (controllers, simulation settings, scene, disturbances).
        scene: the run's world (robot, obstacles, payloads; `RunContext.scene`).
        metric: the metric the controllers are built with.
        reference: the reference they track.
        q0: (nv,) initial joint positions [rad].
        v0: (nv,) initial joint velocities [rad/s].
        prefix: the runs are stored as ``{prefix}{label}`` (see `build.sim_arrays`).
        advance: called after each run (progress).
        duration: simulated time [s]; None: ``simulation.duration``.
        each: called with (label, result) after each run (videos, ...).

    Returns:
        The per-tick arrays of every run.
    """
    out: dict[str, np.ndarray] = {}
    robot = scene.robot
    for label, ccfg in zip(cfg.controller_labels(), cfg.controllers, strict=True):
        ctrl = B.build_controller(ccfg, robot, metric, cfg.simulation.control_dt, scene.obstacles)
        res = B.simulate(cfg, robot, ctrl, reference, q0, v0, duration=duration, scene=scene)
        out.update(B.sim_arrays(f"{prefix}{label}", res))
        if each is not None:
            each(label, res)
        advance()
    return out


class PathComparison(Procedure):
    """Paths between the same configurations, each tracked by every controller.

    ``run`` stores the runs of path ``name`` and controller ``label`` as
    ``{name}_{label}`` (see `track_with_each_controller`). A summary row is the path
    name with one controller, ``{name}_{label}`` with several; `path_summary` gives a
    row's metrics, in table order.
    """

    #: The compared paths, in table and plot order.
    paths: ClassVar[tuple[str, ...]]

    @abstractmethod
    def path_summary(
        self, results: dict[str, np.ndarray], name: str, run: dict[str, np.ndarray], dt: float
    ) -> dict[str, float]:
        """Metrics of path ``name`` tracked in ``run`` (ticks of ``dt`` [s]), by metric name."""

    def summarize(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray]
    ) -> dict[str, float]:
        out: dict[str, float] = {}
        single = len(cfg.controllers) == 1
        for name in self.paths:
            for label in cfg.controller_labels():
                run = B.sim_view(results, f"{name}_{label}")
                row = name if single else f"{name}_{label}"
                metrics = self.path_summary(results, name, run, cfg.simulation.control_dt)
                out |= {f"{row}.{key}": value for key, value in metrics.items()}
        return out

    def run_rows(self, cfg: ExperimentConfig, results: dict[str, np.ndarray]) -> dict[str, str]:
        single = len(cfg.controllers) == 1
        return {
            f"{name}_{label}": name if single else f"{name}_{label}"
            for name in self.paths
            for label in cfg.controller_labels()
        }

    def comparison_plots(
        self, cfg: ExperimentConfig, results: dict[str, np.ndarray], out_dir: Path
    ) -> tuple[dict[str, dict[str, np.ndarray]], list[Path]]:
        """Torques, tracking errors and efforts of the paths tracked by the first controller.

        Returns:
            (path name -> its run arrays, the PNG files written into ``out_dir``).
        """
        label = cfg.controller_labels()[0]
        runs = {name: B.sim_view(results, f"{name}_{label}") for name in self.paths}
        dt = cfg.simulation.control_dt
        efforts = [B.effort(r["tau_applied"], dt) for r in runs.values()]
        return runs, [
            torque_plot(out_dir / "torques.png", runs, B.build_robot(cfg).tau_max),
            tracking_error_plot(out_dir / "tracking_error.png", runs),
            bar_plot(out_dir / "effort.png", list(self.paths), efforts, EFFORT_LABEL, "effort"),
        ]
