"""Synergies learned from human motion: data sources (pinned wheels), the MyoArm as a
robot, motion capture to joint angles, segmentation, and transfer to robots."""

from geosyn.synergies.human.data import (
    HOLOSOMA,
    MYO_SIM,
    MocapSequence,
    Provenance,
    WheelPin,
    clear_data_cache,
    climb_sequences,
    data_dir,
)
from geosyn.synergies.human.errors import DataSourceError
from geosyn.synergies.human.mocap_ik import (
    ArmFit,
    Calibration,
    RootOffset,
    calibrate,
    fit_sequence,
)
from geosyn.synergies.human.myoarm import HumanArm, MuscleInfo, load_myoarm, myoarm_xml

__all__ = [
    "HOLOSOMA",
    "MYO_SIM",
    "ArmFit",
    "Calibration",
    "DataSourceError",
    "HumanArm",
    "MocapSequence",
    "MuscleInfo",
    "Provenance",
    "RootOffset",
    "WheelPin",
    "calibrate",
    "clear_data_cache",
    "climb_sequences",
    "data_dir",
    "fit_sequence",
    "load_myoarm",
    "myoarm_xml",
]
