"""The experiment config: the simulation and output settings, the top-level model
`ExperimentConfig`, and the checks that involve several sections (`consistency_errors`)."""

from __future__ import annotations

import importlib.util
import re
from typing import Annotated, Any, Literal

from pydantic import Field, field_validator, model_validator

from geosyn.experiments.schema.controllers import ControllerConfig
from geosyn.experiments.schema.disturbances import DisturbanceConfig
from geosyn.experiments.schema.metric import MetricConfig
from geosyn.experiments.schema.scene import RobotConfig, SceneConfig
from geosyn.experiments.schema.section import Section, Strict, python_defaults
from geosyn.experiments.schema.stance import StanceConfig
from geosyn.experiments.schema.synergies import ReferenceConfig, SynergyConfig
from geosyn.experiments.schema.values import PositiveFloat
from geosyn.sim import Simulation, render_video

#: Integrators MuJoCo offers (``Simulation(integrator=...)``).
INTEGRATORS = ("implicitfast", "implicit", "Euler", "RK4")

_SIMULATION = python_defaults(Simulation, Simulation.run)
_VIDEO = python_defaults(render_video)


class SimulationConfig(Section):
    """Settings of `geosyn.sim.Simulation` and the duration of its runs [s]."""

    builds = (Simulation, Simulation.run)
    duration: PositiveFloat = _SIMULATION["duration"]
    control_dt: PositiveFloat = _SIMULATION["control_dt"]
    substeps: Annotated[int, Field(ge=1, le=1000)] = _SIMULATION["substeps"]
    integrator: Literal["implicitfast", "implicit", "Euler", "RK4"] = _SIMULATION["integrator"]
    torque_limits: bool = _SIMULATION["torque_limits"]
    position_limits: bool = _SIMULATION["position_limits"]
    mesh_resolution: Annotated[float, Field(gt=0.0, le=1.0, allow_inf_nan=False)] | None = (
        _SIMULATION["mesh_resolution"]
    )

    @model_validator(mode="before")
    @classmethod
    def _contact_is_a_scene_option(cls, data: Any) -> Any:
        if isinstance(data, dict) and "contact" in data:
            raise ValueError(
                "'contact' is not a simulation setting: set scene.contact:"
                f" {str(data['contact']).lower()} (whether the obstacles collide with the robot)"
            )
        return data

    @model_validator(mode="after")
    def _at_least_one_tick(self) -> SimulationConfig:
        if self.duration < self.control_dt:
            raise ValueError(
                f"duration={self.duration} s must be >= control_dt={self.control_dt} s"
            )
        return self


class OutputsConfig(Section):
    """What a run writes: plots, per-run CSV tables (``data/<run>.csv``,
    `geosyn.experiments.results.data`), the same tables as Parquet (``data/<run>.parquet``,
    needs the ``parquet`` extra), and videos (`geosyn.sim.render_video` settings)."""

    builds = (render_video,)
    plots: bool = True
    csv: bool = True
    parquet: bool = False
    video: bool = False
    video_format: Literal["gif", "mp4"] = "gif"
    fps: Annotated[float, Field(gt=0.0, le=120.0)] = _VIDEO["fps"]
    width: Annotated[int, Field(ge=16, le=4096)] = _VIDEO["width"]
    height: Annotated[int, Field(ge=16, le=4096)] = _VIDEO["height"]
    trail: bool = _VIDEO["trail"]

    @field_validator("parquet")
    @classmethod
    def _pyarrow_installed(cls, value: bool) -> bool:
        if value and importlib.util.find_spec("pyarrow") is None:
            raise ValueError(
                "needs pyarrow, which is not installed: pip install 'geosyn[parquet]'"
                " (or set outputs.parquet: false)"
            )
        return value


_NAME = re.compile(r"^[A-Za-z0-9_\-.]+$")


class ExperimentConfig(Strict):
    """One experiment: what to build, what to run, what to write.

    ``kind`` names the registered procedure that runs it
    (`geosyn.experiments.procedures.PROCEDURES`); ``params`` are that procedure's own
    settings, validated by its ``Params`` model (also with unknown keys rejected).
    """

    name: Annotated[str, Field(pattern=_NAME.pattern, min_length=1, max_length=100)]
    description: str = ""
    kind: str
    seed: Annotated[int, Field(ge=0, le=2**31 - 1)] = 0
    robot: RobotConfig
    metric: MetricConfig = MetricConfig()
    scene: SceneConfig = SceneConfig()
    stance: StanceConfig | None = None
    synergies: SynergyConfig | None = None
    reference: ReferenceConfig | None = None
    controllers: list[ControllerConfig] = []
    disturbances: list[DisturbanceConfig] = []
    simulation: SimulationConfig = SimulationConfig()
    outputs: OutputsConfig = OutputsConfig()
    params: dict[str, Any] = {}

    def controller_labels(self) -> list[str]:
        """Unique label of each controller: its ``label`` or its type (numbered if repeated)."""
        base = [c.label or c.type for c in self.controllers]
        out = []
        for i, b in enumerate(base):
            out.append(b if base.count(b) == 1 else f"{b}{base[: i + 1].count(b)}")
        return out


def _out_of_range(path: str, index: int, n_payloads: int) -> tuple[str, str]:
    return (path, f"index {index} out of range: {n_payloads} payload(s) in scene.payloads")


def consistency_errors(cfg: ExperimentConfig, nv: int) -> list[tuple[str, str]]:
    """Cross-field problems of a validated config, as ``(field path, reason)`` pairs.

    Args:
        cfg: the validated config.
        nv: the robot's number of velocity DoF.
    """
    errors: list[tuple[str, str]] = []
    n_pay = len(cfg.scene.payloads)
    syn = cfg.synergies
    if syn is not None and syn.type in ("designed", "pga") and syn.k > nv:
        errors.append(("synergies.k", f"must be <= the robot's DoF {nv}, got {syn.k}"))
    if syn is not None and syn.type == "pga" and syn.latent > nv:
        errors.append(("synergies.latent", f"must be <= the robot's DoF {nv}, got {syn.latent}"))
    ref = cfg.reference
    if ref is not None and ref.type == "combination":
        if syn is None:
            errors.append(("reference", "a combination reference needs a synergies section"))
        else:
            m = len(syn.items) if syn.type == "explicit" else syn.k
            if len(ref.weights) != m:
                reason = f"expected one weight per synergy ({m}), got {len(ref.weights)}"
                errors.append(("reference.weights", reason))
    if ref is not None and ref.type == "goals" and isinstance(ref.duration, list):
        if len(ref.duration) != len(ref.goals):
            reason = f"expected one duration per goal ({len(ref.goals)}), got {len(ref.duration)}"
            errors.append(("reference.duration", reason))
    for i, term in enumerate(cfg.metric.terms):
        if term.type == "load" and term.payload is not None and term.payload >= n_pay:
            errors.append(_out_of_range(f"metric.terms.{i}.payload", term.payload, n_pay))
        if term.type == "obstacle" and not cfg.scene.has_obstacles:
            errors.append(
                (f"metric.terms.{i}", "an obstacle term needs scene.obstacles or scene.mjcf")
            )
    if cfg.scene.contact and not cfg.scene.has_obstacles:
        errors.append(
            ("scene.contact", "true needs scene.obstacles or scene.mjcf (nothing to collide)")
        )
    for i, dist in enumerate(cfg.disturbances):
        if (
            dist.type == "payload_change"
            and isinstance(dist.payload, int)
            and dist.payload >= n_pay
        ):
            errors.append(_out_of_range(f"disturbances.{i}.payload", dist.payload, n_pay))
    labels = [c.label for c in cfg.controllers if c.label is not None]
    for i, c in enumerate(cfg.controllers):
        if c.label is not None and labels.count(c.label) > 1:
            errors.append((f"controllers.{i}.label", f"duplicate label {c.label!r}"))
            break
    return errors


__all__ = [
    "INTEGRATORS",
    "ExperimentConfig",
    "OutputsConfig",
    "SimulationConfig",
    "consistency_errors",
]
