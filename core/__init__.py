"""Core of geosyn: the error base and shared array type aliases. Nothing else."""

from geosyn.core.errors import GeosynError, InvalidArgument
from geosyn.core.types import Array, Matrix, Vector

__all__ = ["Array", "GeosynError", "InvalidArgument", "Matrix", "Vector"]
