"""Geodesic synergies: combination by parallel transport, orthonormal bases, PGA, reaching,
sequences of synergies and the fitted map from target positions to weights."""

if not __name__.startswith("geosyn."):  # the folder imported as a top-level package
    raise ImportError(f"import geosyn.synergies, not {__name__}: one module, one name")


from geosyn.synergies.basis import SynergyBasis, g_orthonormalize, orthonormal_synergies
from geosyn.synergies.errors import InvalidSynergyInput, SynergyError, SynergyNotConverged
from geosyn.synergies.perception_map import MapSolution, SynergyMap
from geosyn.synergies.pga import PCAResult, PGAResult, frechet_mean, pca_synergies, pga
from geosyn.synergies.reach import ReachOutsideLimits, ReachResult, reach
from geosyn.synergies.sequence import (
    SequenceSegment,
    SynergySequence,
    geodesic_sequence,
    reach_sequence,
    straight_sequence,
)
from geosyn.synergies.synergy import GeodesicSynergy, combine, transported_velocities

__all__ = [
    "GeodesicSynergy",
    "InvalidSynergyInput",
    "MapSolution",
    "PCAResult",
    "PGAResult",
    "ReachOutsideLimits",
    "ReachResult",
    "SequenceSegment",
    "SynergyBasis",
    "SynergyError",
    "SynergyMap",
    "SynergyNotConverged",
    "SynergySequence",
    "combine",
    "frechet_mean",
    "g_orthonormalize",
    "geodesic_sequence",
    "orthonormal_synergies",
    "pca_synergies",
    "pga",
    "reach",
    "reach_sequence",
    "straight_sequence",
    "transported_velocities",
]
