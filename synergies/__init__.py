"""Geodesic synergies: combination by parallel transport, orthonormal bases, PGA, reaching."""

if not __name__.startswith("geosyn."):  # the folder imported as a top-level package
    raise ImportError(f"import geosyn.synergies, not {__name__}: one module, one name")


from geosyn.synergies.basis import SynergyBasis, g_orthonormalize, orthonormal_synergies
from geosyn.synergies.errors import InvalidSynergyInput, SynergyError, SynergyNotConverged
from geosyn.synergies.pga import PCAResult, PGAResult, frechet_mean, pca_synergies, pga
from geosyn.synergies.reach import ReachResult, reach
from geosyn.synergies.synergy import GeodesicSynergy, combine, transported_velocities

__all__ = [
    "GeodesicSynergy",
    "InvalidSynergyInput",
    "PCAResult",
    "PGAResult",
    "ReachResult",
    "SynergyBasis",
    "SynergyError",
    "SynergyNotConverged",
    "combine",
    "frechet_mean",
    "g_orthonormalize",
    "orthonormal_synergies",
    "pca_synergies",
    "pga",
    "reach",
    "transported_velocities",
]
