"""The typed experiment configuration: pydantic models that reject unknown keys.

An experiment file (YAML) is validated into an `ExperimentConfig`. Every model forbids
unknown keys; shaping terms, obstacles, synergy sources, references, controllers and
disturbances are discriminated unions on their ``type`` field, so a config selects
registered Python classes by name and never carries code.

Joint-space vectors (``q0``, ``goal``, per-joint gains, ...) are checked against the
robot's number of degrees of freedom: the loader validates ``robot`` first, loads the
robot and passes ``{"nv": robot.nv}`` as the pydantic validation context (see
`geosyn.experiments.loader`). Without a context only the types are checked.

Checks that involve several fields (the number of weights against the number of
synergies, a payload index against the payloads, ...) are in `consistency_errors`.
"""

from __future__ import annotations

import math
import re
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    ValidationInfo,
    field_validator,
    model_validator,
)

#: Integrators MuJoCo offers (``Simulation(integrator=...)``).
INTEGRATORS = ("implicitfast", "implicit", "Euler", "RK4")

FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
NonNegFloat = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]
PositiveFloat = Annotated[float, Field(gt=0.0, allow_inf_nan=False)]
Vec3 = Annotated[list[FiniteFloat], Field(min_length=3, max_length=3)]


def _check_nv(value: list[float], info: ValidationInfo) -> list[float]:
    """Length check of a joint-space vector against ``context["nv"]`` (when given)."""
    nv = (info.context or {}).get("nv")
    if nv is not None and len(value) != nv:
        raise ValueError(f"expected {nv} values (the robot's DoF), got {len(value)}")
    return value


#: (nv,) joint-space vector [rad, rad/s, ...], length checked against the robot.
JointVector = Annotated[list[FiniteFloat], AfterValidator(_check_nv)]
#: A gain: one number for all joints, or one per joint, all >= 0.
Gain = NonNegFloat | Annotated[list[NonNegFloat], AfterValidator(_check_nv)]


class Strict(BaseModel):
    """Base of every config model: unknown keys are errors."""

    model_config = ConfigDict(extra="forbid")


# -- robot -------------------------------------------------------------------------------
class RobotOptions(Strict):
    """Options of `geosyn.robots.load_robot` (only these are accepted)."""

    armature: NonNegFloat | None = None
    gravity: Vec3 | None = None
    ee_frame: str | None = None


class RobotConfig(Strict):
    """The robot: a built-in name (see ``geosyn robots``) or a URDF/MJCF path."""

    name: str
    options: RobotOptions = RobotOptions()

    @field_validator("name")
    @classmethod
    def _known(cls, name: str) -> str:
        from geosyn.robots import BUILTINS

        if name in BUILTINS or name.lower().endswith((".urdf", ".xml", ".mjcf")):
            return name
        raise ValueError(
            f"{name!r} is not a built-in robot; available: {', '.join(sorted(BUILTINS))}"
            " (or a path to a .urdf/.xml/.mjcf file)"
        )


# -- scene -------------------------------------------------------------------------------
class SphereConfig(Strict):
    type: Literal["sphere"]
    center: Vec3
    radius: PositiveFloat


class BoxConfig(Strict):
    type: Literal["box"]
    center: Vec3
    half_extents: Annotated[list[PositiveFloat], Field(min_length=3, max_length=3)]
    #: orientation as roll, pitch, yaw [rad] about the world's x, y, z (URDF convention:
    #: R = Rz(yaw) Ry(pitch) Rx(roll)).
    rpy: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])


class CapsuleConfig(Strict):
    type: Literal["capsule"]
    p0: Vec3
    p1: Vec3
    radius: PositiveFloat


class HalfSpaceConfig(Strict):
    """``{x : normal . x <= offset}`` is the obstacle; ``normal`` is normalised."""

    type: Literal["halfspace"]
    normal: Vec3
    offset: FiniteFloat

    @field_validator("normal")
    @classmethod
    def _nonzero(cls, n: list[float]) -> list[float]:
        norm = math.sqrt(sum(x * x for x in n))
        if norm < 1e-12:
            raise ValueError("normal must be a nonzero vector")
        return [x / norm for x in n]


ObstacleConfig = Annotated[
    SphereConfig | BoxConfig | CapsuleConfig | HalfSpaceConfig, Field(discriminator="type")
]


class PayloadConfig(Strict):
    """A solid sphere welded to a link (`geosyn.sim.Payload`)."""

    frame: str | None = None  # default: the robot's end-effector frame
    mass: NonNegFloat
    offset: Vec3 = [0.0, 0.0, 0.0]
    radius: PositiveFloat = 0.03
    name: str | None = None


class SceneConfig(Strict):
    """Payload bodies and obstacles of the MuJoCo scene (also seen by shaping terms)."""

    payloads: list[PayloadConfig] = []
    obstacles: list[ObstacleConfig] = []


# -- metric ------------------------------------------------------------------------------
class LoadTermConfig(Strict):
    """`LoadTerm`: either ``payload`` (index into ``scene.payloads``) or ``frame``+``mass``."""

    type: Literal["load"]
    payload: Annotated[int, Field(ge=0)] | None = None
    frame: str | None = None
    mass: PositiveFloat | None = None
    com: Vec3 = [0.0, 0.0, 0.0]

    @model_validator(mode="after")
    def _one_source(self) -> LoadTermConfig:
        if self.payload is None and self.mass is None:
            raise ValueError("give either payload (an index into scene.payloads) or mass [kg]")
        if self.payload is not None and (self.mass is not None or self.frame is not None):
            raise ValueError("give either payload or frame/mass, not both")
        return self


class ObstacleTermConfig(Strict):
    """`ObstacleTerm` over the scene's obstacles."""

    type: Literal["obstacle"]
    profile: Literal["inverse_square", "rmp"] = "inverse_square"
    gain: PositiveFloat = 1e-3
    cutoff: PositiveFloat = 0.2
    d_min: PositiveFloat = 1e-4
    gate: Literal["none", "approach"] = "none"


class JointLimitTermConfig(Strict):
    """`JointLimitTerm`."""

    type: Literal["joint_limit"]
    margin: PositiveFloat = 0.2
    gain: PositiveFloat = 1e-3


TermConfig = Annotated[
    LoadTermConfig | ObstacleTermConfig | JointLimitTermConfig, Field(discriminator="type")
]


class MetricConfig(Strict):
    """Kinetic-energy metric of the robot plus shaping terms."""

    terms: list[TermConfig] = []


# -- synergies ---------------------------------------------------------------------------
class ExplicitSynergy(Strict):
    q0: JointVector
    v0: JointVector


class ExplicitSynergies(Strict):
    """Synergies given by their base configuration and initial velocity."""

    type: Literal["explicit"]
    items: Annotated[list[ExplicitSynergy], Field(min_length=1)]


class DesignedSynergies(Strict):
    """``orthonormal_synergies(metric, q0, k)``: G-orthonormal, ordered by hand motion."""

    type: Literal["designed"]
    q0: JointVector
    k: Annotated[int, Field(ge=1)]
    frame: str | None = None


class PGASynergies(Strict):
    """PGA of generated demonstrations: ``n_demos`` endpoints of geodesics from ``q0``
    with random G-orthonormal-basis velocities of standard deviation ``spread``."""

    type: Literal["pga"]
    q0: JointVector
    k: Annotated[int, Field(ge=1)]
    n_demos: Annotated[int, Field(ge=2, le=500)] = 20
    spread: PositiveFloat = 0.5
    latent: Annotated[int, Field(ge=1)] = 2


SynergyConfig = Annotated[
    ExplicitSynergies | DesignedSynergies | PGASynergies, Field(discriminator="type")
]


# -- references --------------------------------------------------------------------------
class CombinationReference(Strict):
    """``combine(synergies, weights, q_start)`` traversed over ``duration * time_scale``."""

    type: Literal["combination"]
    weights: Annotated[list[FiniteFloat], Field(min_length=1)]
    q_start: JointVector | None = None
    duration: PositiveFloat = 1.0
    time_scale: PositiveFloat = 1.0
    steps: Annotated[int, Field(ge=2, le=100_000)] = 200


class LogReference(Strict):
    """The geodesic from ``q_start`` to ``goal`` (``log`` then ``exp``)."""

    type: Literal["log"]
    q_start: JointVector
    goal: JointVector
    duration: PositiveFloat = 1.0
    time_scale: PositiveFloat = 1.0
    steps: Annotated[int, Field(ge=2, le=100_000)] = 200


ReferenceConfig = Annotated[CombinationReference | LogReference, Field(discriminator="type")]


# -- controllers -------------------------------------------------------------------------
class _ControllerBase(Strict):
    label: Annotated[str, Field(pattern=r"^[A-Za-z0-9_\-]+$")] | None = None


class ComputedTorqueConfig(_ControllerBase):
    type: Literal["computed_torque"]
    kp: Gain = 400.0
    kd: Gain = 40.0


class RiemannianPDConfig(_ControllerBase):
    type: Literal["riemannian_pd"]
    lam: Gain = 20.0
    k: Gain = 50.0


class QPConfig(_ControllerBase):
    type: Literal["qp"]
    kp: Gain = 400.0
    kd: Gain = 40.0
    eps: PositiveFloat = 1e-6
    position_horizon: PositiveFloat | None = None
    braking_acceleration: PositiveFloat | None = None
    max_iter: Annotated[int, Field(ge=1)] = 1000


class MPCConfig(_ControllerBase):
    type: Literal["mpc"]
    horizon: Annotated[int, Field(ge=1, le=1000)] = 10
    dt: PositiveFloat = 0.02
    solver: Literal["fatrop", "ipopt"] = "fatrop"
    q_weight: NonNegFloat = 1e4
    v_weight: NonNegFloat = 1e1
    tau_weight: NonNegFloat = 1e-3
    terminal_weight: NonNegFloat = 1e5
    effort: Literal["torque", "metric"] = "torque"
    control: Literal["torque", "acceleration"] = "torque"
    kp: Gain = 400.0
    kd: Gain = 40.0
    max_iter: Annotated[int, Field(ge=1)] = 50


ControllerConfig = Annotated[
    ComputedTorqueConfig | RiemannianPDConfig | QPConfig | MPCConfig, Field(discriminator="type")
]


# -- disturbances ------------------------------------------------------------------------
class PushConfig(Strict):
    type: Literal["push"]
    body: str
    force: Vec3
    start: NonNegFloat
    duration: PositiveFloat
    point: Vec3 | None = None


class WrenchConfig(Strict):
    type: Literal["wrench"]
    body: str
    force: Vec3 = [0.0, 0.0, 0.0]
    torque: Vec3 = [0.0, 0.0, 0.0]
    period: PositiveFloat | None = None
    start: NonNegFloat = 0.0
    stop: PositiveFloat | None = None  # None: never stops


class PayloadChangeConfig(Strict):
    type: Literal["payload_change"]
    time: NonNegFloat
    mass: NonNegFloat
    payload: Annotated[int, Field(ge=0)] | str = 0


class TorqueNoiseConfig(Strict):
    type: Literal["torque_noise"]
    std: Gain


class SensorNoiseConfig(Strict):
    type: Literal["sensor_noise"]
    q_std: Gain = 0.0
    v_std: Gain = 0.0


class LatencyConfig(Strict):
    type: Literal["latency"]
    ticks: Annotated[int, Field(ge=0)] | None = None
    seconds: NonNegFloat | None = None

    @model_validator(mode="after")
    def _exactly_one(self) -> LatencyConfig:
        if (self.ticks is None) == (self.seconds is None):
            raise ValueError("give exactly one of ticks or seconds")
        return self


DisturbanceConfig = Annotated[
    PushConfig
    | WrenchConfig
    | PayloadChangeConfig
    | TorqueNoiseConfig
    | SensorNoiseConfig
    | LatencyConfig,
    Field(discriminator="type"),
]


# -- simulation, outputs -----------------------------------------------------------------
class SimulationConfig(Strict):
    """Settings of `geosyn.sim.Simulation` and of the run."""

    duration: PositiveFloat = 2.0
    control_dt: PositiveFloat = 1e-3
    substeps: Annotated[int, Field(ge=1, le=1000)] = 1
    integrator: Literal["implicitfast", "implicit", "Euler", "RK4"] = "implicitfast"

    @model_validator(mode="after")
    def _at_least_one_tick(self) -> SimulationConfig:
        if self.duration < self.control_dt:
            raise ValueError(
                f"duration={self.duration} s must be >= control_dt={self.control_dt} s"
            )
        return self


class OutputsConfig(Strict):
    plots: bool = True
    video: bool = False
    video_format: Literal["gif", "mp4"] = "gif"
    fps: Annotated[float, Field(gt=0.0, le=120.0)] = 25.0
    width: Annotated[int, Field(ge=16, le=4096)] = 480
    height: Annotated[int, Field(ge=16, le=4096)] = 360


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
                errors.append(
                    (
                        "reference.weights",
                        f"expected one weight per synergy ({m}), got {len(ref.weights)}",
                    )
                )
    for i, term in enumerate(cfg.metric.terms):
        if term.type == "load" and term.payload is not None and term.payload >= n_pay:
            errors.append(
                (
                    f"metric.terms.{i}.payload",
                    f"index {term.payload} out of range: {n_pay} payload(s) in scene.payloads",
                )
            )
        if term.type == "obstacle" and not cfg.scene.obstacles:
            errors.append((f"metric.terms.{i}", "an obstacle term needs scene.obstacles"))
    for i, dist in enumerate(cfg.disturbances):
        if (
            dist.type == "payload_change"
            and isinstance(dist.payload, int)
            and dist.payload >= n_pay
        ):
            errors.append(
                (
                    f"disturbances.{i}.payload",
                    f"index {dist.payload} out of range: {n_pay} payload(s) in scene.payloads",
                )
            )
    labels = [c.label for c in cfg.controllers if c.label is not None]
    for i, c in enumerate(cfg.controllers):
        if c.label is not None and labels.count(c.label) > 1:
            errors.append((f"controllers.{i}.label", f"duplicate label {c.label!r}"))
            break
    return errors


__all__ = [
    "INTEGRATORS",
    "BoxConfig",
    "CapsuleConfig",
    "CombinationReference",
    "ComputedTorqueConfig",
    "ControllerConfig",
    "DesignedSynergies",
    "DisturbanceConfig",
    "ExperimentConfig",
    "ExplicitSynergies",
    "ExplicitSynergy",
    "HalfSpaceConfig",
    "JointLimitTermConfig",
    "LatencyConfig",
    "LoadTermConfig",
    "LogReference",
    "MPCConfig",
    "MetricConfig",
    "ObstacleConfig",
    "ObstacleTermConfig",
    "OutputsConfig",
    "PGASynergies",
    "PayloadChangeConfig",
    "PayloadConfig",
    "PushConfig",
    "QPConfig",
    "ReferenceConfig",
    "RiemannianPDConfig",
    "RobotConfig",
    "RobotOptions",
    "SceneConfig",
    "SensorNoiseConfig",
    "SimulationConfig",
    "SphereConfig",
    "Strict",
    "SynergyConfig",
    "TermConfig",
    "TorqueNoiseConfig",
    "WrenchConfig",
    "consistency_errors",
]
