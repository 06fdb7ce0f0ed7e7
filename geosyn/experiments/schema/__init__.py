"""The typed experiment configuration: pydantic models that reject unknown keys.

An experiment file (YAML) is validated into an `ExperimentConfig`. Every model forbids
unknown keys; shaping terms, obstacles, synergy sources, references, controllers and
disturbances are discriminated unions on their ``type`` field, so a config selects
registered Python classes by name and never carries code.

Defaults have one source: a section that stands for a library class (a controller, a
shaping term, a disturbance, the simulation, ...) reads each default from that class's
signature (`python_defaults`), so a YAML default is the Python default.

Joint-space vectors (``q0``, ``goal``, per-joint gains, ...) are checked against the
robot's number of degrees of freedom: the loader validates ``robot`` first, loads the
robot and passes ``{"nv": robot.nv}`` as the pydantic validation context (see
`geosyn.experiments.config.loader`). Without a context only the types are checked.

Checks that involve several fields (the number of weights against the number of
synergies, a payload index against the payloads, ...) are in `consistency_errors`.

Modules: `section` (strict base, `Section`, defaults from signatures), `values` (value
types of fields), `scene` (robot, obstacles, payloads), `metric`, `synergies` (synergies
and references), `controllers`, `stance` (a floating robot's stance and its reference),
`disturbances`, `experiment` (simulation, outputs, the
whole config).
"""

from geosyn.experiments.schema.controllers import (
    ComputedTorqueConfig,
    ControllerConfig,
    MPCConfig,
    QPConfig,
    RiemannianPDConfig,
    WholeBodyConfig,
)
from geosyn.experiments.schema.disturbances import (
    DisturbanceConfig,
    LatencyConfig,
    PayloadChangeConfig,
    PushConfig,
    SensorNoiseConfig,
    TorqueNoiseConfig,
    WrenchConfig,
)
from geosyn.experiments.schema.experiment import (
    INTEGRATORS,
    ExperimentConfig,
    OutputsConfig,
    SimulationConfig,
    consistency_errors,
)
from geosyn.experiments.schema.metric import (
    JointLimitTermConfig,
    LoadTermConfig,
    MetricConfig,
    ObstacleTermConfig,
    TermConfig,
)
from geosyn.experiments.schema.scene import (
    BoxConfig,
    CapsuleConfig,
    HalfSpaceConfig,
    ObstacleConfig,
    PayloadConfig,
    RobotConfig,
    RobotOptions,
    SceneConfig,
    SphereConfig,
)
from geosyn.experiments.schema.section import Section, Strict, python_defaults
from geosyn.experiments.schema.stance import (
    StanceConfig,
    StanceSynergyReferenceConfig,
    SynergyDirection,
)
from geosyn.experiments.schema.synergies import (
    CombinationReference,
    DesignedSynergies,
    ExplicitSynergies,
    ExplicitSynergy,
    GoalsReference,
    LogReference,
    PGASynergies,
    PlannedReference,
    ReferenceConfig,
    SynergyConfig,
)
from geosyn.experiments.schema.values import (
    FiniteFloat,
    Gain,
    JointVector,
    NonNegFloat,
    PositiveFloat,
    Vec3,
)

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
    "FiniteFloat",
    "Gain",
    "GoalsReference",
    "HalfSpaceConfig",
    "JointLimitTermConfig",
    "JointVector",
    "LatencyConfig",
    "LoadTermConfig",
    "LogReference",
    "MPCConfig",
    "MetricConfig",
    "NonNegFloat",
    "ObstacleConfig",
    "ObstacleTermConfig",
    "OutputsConfig",
    "PGASynergies",
    "PayloadChangeConfig",
    "PayloadConfig",
    "PlannedReference",
    "PositiveFloat",
    "PushConfig",
    "QPConfig",
    "ReferenceConfig",
    "RiemannianPDConfig",
    "RobotConfig",
    "RobotOptions",
    "SceneConfig",
    "Section",
    "SensorNoiseConfig",
    "SimulationConfig",
    "SphereConfig",
    "StanceConfig",
    "StanceSynergyReferenceConfig",
    "Strict",
    "SynergyDirection",
    "SynergyConfig",
    "TermConfig",
    "TorqueNoiseConfig",
    "Vec3",
    "WholeBodyConfig",
    "WrenchConfig",
    "consistency_errors",
    "python_defaults",
]
