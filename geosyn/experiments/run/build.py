"""Building library objects from a validated config: metric, synergies, reference,
controllers, disturbances, simulations (the robot and the world: `geosyn.experiments.run.scene`,
whose builders are re-exported here). Each config ``type`` maps to a builder through a
registry dict (no string if/elif factories, no code in configs); a section's settings
reach their class as `Section.kwargs` (the fields named like the class's parameters).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from geosyn.controllers import (
    ComputedTorque,
    Controller,
    GeodesicMPC,
    QPController,
    RiemannianPD,
)
from geosyn.core.errors import InvalidArgument
from geosyn.experiments import schema as S
from geosyn.experiments.run.references import (
    build_reference,
    reference_geodesic,
    tracked_reference,
)
from geosyn.experiments.run.scene import (
    OBSTACLES,
    BuiltScene,
    build_obstacles,
    build_payloads,
    build_robot,
    build_run_scene,
)
from geosyn.metrics import KineticEnergyMetric, Metric
from geosyn.metrics.geodesic import exp
from geosyn.metrics.shaping import (
    JointLimitTerm,
    LoadTerm,
    MetricTerm,
    ObstacleTerm,
    ShapedMetric,
)
from geosyn.robots import Robot
from geosyn.sim import (
    Disturbance,
    Latency,
    PayloadChange,
    Push,
    SensorNoise,
    SimResult,
    Simulation,
    TorqueNoise,
    Wrench,
)
from geosyn.sim.log import ARRAY_FIELDS, RUN_META
from geosyn.synergies import GeodesicSynergy, orthonormal_synergies, pga
from geosyn.synergies.demonstrations import load_demonstrations
from geosyn.world import Payload, Shape


def _load_term(t: S.LoadTermConfig, scene: BuiltScene) -> MetricTerm:
    if t.payload is not None:
        return LoadTerm.from_payload(scene.payloads[t.payload])
    return LoadTerm(**(t.kwargs() | {"frame": t.frame or scene.robot.ee_frame}))


TERMS: dict[str, Callable[[Any, BuiltScene], MetricTerm]] = {
    "load": _load_term,
    "obstacle": lambda t, scene: ObstacleTerm(
        list(scene.obstacles), capacity=max(1, len(scene.obstacles)), **t.kwargs()
    ),
    "joint_limit": lambda t, scene: JointLimitTerm(**t.kwargs()),
}
"""Registry of metric-term builders by config ``type``: (section, scene) -> term."""


def build_metric(
    cfg: S.ExperimentConfig,
    robot: Robot,
    terms: Sequence[S.TermConfig] | None = None,
    *,
    scene: BuiltScene | None = None,
) -> Metric:
    """The kinetic-energy metric, shaped by ``terms`` (default: the config's terms).

    The obstacle and load terms read the run's ``scene`` (`build_run_scene`; built from
    the config when not given).
    """
    base = KineticEnergyMetric(robot)
    terms = cfg.metric.terms if terms is None else terms
    if not terms:
        return base
    scene = build_run_scene(cfg, robot) if scene is None else scene
    return ShapedMetric(base, [TERMS[t.type](t, scene) for t in terms])


def _explicit(
    s: S.ExplicitSynergies, metric: Metric, robot: Robot, seed: int
) -> list[GeodesicSynergy]:
    return [GeodesicSynergy(metric, np.array(i.q0), np.array(i.v0)) for i in s.items]


def _designed(
    s: S.DesignedSynergies, metric: Metric, robot: Robot, seed: int
) -> list[GeodesicSynergy]:
    basis = orthonormal_synergies(metric, np.array(s.q0), s.k, frame=s.frame, robot=robot)
    return list(basis.synergies)


def pga_demonstrations(
    metric: Metric,
    robot: Robot,
    q0: np.ndarray,
    n_demos: int,
    spread: float,
    latent: int,
    seed: int,
) -> np.ndarray:
    """(n_demos, n) demonstration endpoints ``exp(q0, sum_j c_j e_j)``, ``c ~ N(0, spread^2)``
    over the first ``latent`` designed synergy directions ``e_j`` at ``q0`` (G-orthonormal).
    """
    basis = orthonormal_synergies(metric, q0, latent, robot=robot)
    rng = np.random.default_rng(seed)
    coeffs = rng.normal(0.0, spread, size=(n_demos, latent))
    return np.array([exp(metric, q0, basis.V @ c, 1.0, 100).q[-1] for c in coeffs])


def _pga(s: S.PGASynergies, metric: Metric, robot: Robot, seed: int) -> list[GeodesicSynergy]:
    demos: np.ndarray | list[np.ndarray]
    if s.demonstrations is not None:  # recorded: in z when the metric is the coupled one
        coupled = robot.coupling is not None and metric.n == robot.coupling.nz
        names = robot.coupling.independent if coupled else robot.joint_names  # type: ignore[union-attr]
        demos = load_demonstrations(s.demonstrations, names, key=s.key)
    else:
        q0 = np.array(s.q0)
        demos = pga_demonstrations(metric, robot, q0, s.n_demos, s.spread, s.latent, seed)
    res = pga(metric, demos, s.k)
    return [GeodesicSynergy(metric, res.mean, res.V[:, j]) for j in range(s.k)]


SYNERGIES: dict[str, Callable[[Any, Metric, Robot, int], list[GeodesicSynergy]]] = {
    "explicit": _explicit,
    "designed": _designed,
    "pga": _pga,
}


def build_synergies(cfg: S.ExperimentConfig, metric: Metric, robot: Robot) -> list[GeodesicSynergy]:
    """The config's synergies on ``metric`` (empty without a synergies section)."""
    if cfg.synergies is None:
        return []
    return SYNERGIES[cfg.synergies.type](cfg.synergies, metric, robot, cfg.seed)


CONTROLLERS: dict[str, Callable[[Any, Robot, Metric, float], Controller]] = {
    "computed_torque": lambda c, robot, metric, dt: ComputedTorque(
        robot, metric=metric, **c.kwargs()
    ),
    "riemannian_pd": lambda c, robot, metric, dt: RiemannianPD(robot, metric=metric, **c.kwargs()),
    "qp": lambda c, robot, metric, dt: QPController(robot, dt=dt, metric=metric, **c.kwargs()),
    "mpc": lambda c, robot, metric, dt: GeodesicMPC(robot, metric, **c.kwargs()),
}
"""Registry of controller builders ``(section, robot, metric, control_dt) -> Controller``."""


def build_controller(
    c: S.ControllerConfig,
    robot: Robot,
    metric: Metric,
    control_dt: float,
    obstacles: Sequence[Shape] = (),
) -> Controller:
    """A controller from its config section (``control_dt`` is the QP's period).

    An MPC with ``clearance_margin`` keeps clear of ``obstacles`` (the scene's, as
    `geosyn.world` shapes: ``GeodesicMPC(..., obstacles=...)``).

    Raises:
        InvalidArgument: ``clearance_margin`` without obstacles in the scene.
    """
    if getattr(c, "clearance_margin", None) is not None:
        if not obstacles:
            raise InvalidArgument(
                "clearance_margin (mpc controller) needs obstacles: list them in scene.obstacles"
            )
        return GeodesicMPC(robot, metric, **c.kwargs(), obstacles=list(obstacles))
    return CONTROLLERS[c.type](c, robot, metric, control_dt)


DISTURBANCES: dict[str, Callable[..., Disturbance]] = {
    "push": Push,
    "wrench": Wrench,
    "payload_change": PayloadChange,
    "torque_noise": TorqueNoise,
    "sensor_noise": SensorNoise,
    "latency": Latency,
}
"""Registry of disturbance classes by config ``type`` (built from the section's kwargs)."""


def build_disturbances(cfg: S.ExperimentConfig) -> list[Disturbance]:
    """The config's disturbances, in order."""
    return [DISTURBANCES[d.type](**d.kwargs()) for d in cfg.disturbances]


def simulate(
    cfg: S.ExperimentConfig,
    robot: Robot,
    controller: Controller,
    reference: Any,
    q0: np.ndarray,
    v0: np.ndarray | None = None,
    *,
    duration: float | None = None,
    disturbances: Sequence[Disturbance] | None = None,
    payloads: Sequence[Payload] | None = None,
    obstacles: Sequence[Shape] | None = None,
    scene: BuiltScene | None = None,
) -> SimResult:
    """Run one closed-loop simulation with the config's simulation settings and seed.

    The world is the run's ``scene`` (`build_run_scene`; built from the config when not
    given); ``payloads`` and ``obstacles`` replace its own when given.
    """
    sim = cfg.simulation
    scene = build_run_scene(cfg, robot) if scene is None else scene
    s = Simulation(
        robot,
        controller,
        payloads=scene.payloads if payloads is None else payloads,
        obstacles=scene.obstacles if obstacles is None else obstacles,
        disturbances=build_disturbances(cfg) if disturbances is None else disturbances,
        seed=cfg.seed,
        plant=scene.plant,
        contact=scene.contact,
        **sim.kwargs(),
    )
    return s.run(q0, v0, sim.duration if duration is None else duration, reference)


#: Arrays of a `SimResult` left out of results.npz: the measured state, the commanded
#: torque before saturation, the reference velocity, solver internals and the final state.
_NOT_SAVED = frozenset(
    {"q_meas", "v_meas", "tau", "v_ref", "compute_time", "iterations", "solver_status"}
    | {"q_final", "v_final"}
)

#: Per-tick fields of a `SimResult` kept in results.npz, in `SimResult` order.
SIM_FIELDS = tuple(f for f in ARRAY_FIELDS if f not in _NOT_SAVED)


def sim_arrays(prefix: str, res: SimResult) -> dict[str, np.ndarray]:
    """The per-tick log of a run as ``{prefix}__{field}`` arrays, plus its status, wall
    time, exact clearance and metadata (``{prefix}__meta``: joint names, control period,
    ...).

    The arrays are the result's own, not copies: a spooled run's stay read-only maps of
    its spool file (`geosyn.sim.log_spool`), written out a block at a time by the runner
    (`geosyn.sim.blocks.save_npz`, `geosyn.experiments.results.data.write_csv`)."""
    out = {f"{prefix}__{f}": np.asarray(getattr(res, f)) for f in SIM_FIELDS}
    out[f"{prefix}__status"] = np.array(res.status)
    out[f"{prefix}__wall_time"] = np.array(res.wall_time)
    out[f"{prefix}__mesh_clearance"] = np.array(res.mesh_clearance)
    out[f"{prefix}{RUN_META}"] = np.array(res.metadata_json())  # SimResult.load(path, run)
    return out


def sim_view(results: dict[str, np.ndarray], prefix: str) -> dict[str, np.ndarray]:
    """The arrays of one run stored by `sim_arrays`, keyed by field name."""
    head = f"{prefix}__"
    return {k[len(head) :]: v for k, v in results.items() if k.startswith(head)}


def effort(tau: np.ndarray, dt: float) -> float:
    """``integral ||tau||^2 dt`` of a (T, nv) torque log held over ticks of ``dt`` [N^2 m^2 s]."""
    return float(np.sum(tau**2) * dt)


__all__ = [
    "CONTROLLERS",
    "DISTURBANCES",
    "OBSTACLES",
    "SIM_FIELDS",
    "SYNERGIES",
    "TERMS",
    "build_controller",
    "build_disturbances",
    "build_metric",
    "build_obstacles",
    "build_payloads",
    "build_reference",
    "build_robot",
    "build_run_scene",
    "build_synergies",
    "effort",
    "pga_demonstrations",
    "reference_geodesic",
    "sim_arrays",
    "sim_view",
    "simulate",
    "tracked_reference",
]
