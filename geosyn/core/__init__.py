"""Core of geosyn: the error base and shared array type aliases. Nothing else."""

if not __name__.startswith("geosyn."):  # the folder imported as a top-level package
    raise ImportError(f"import geosyn.core, not {__name__}: one module, one name")


from geosyn.core.errors import GeosynError, InvalidArgument
from geosyn.core.types import Array, Matrix, Vector

__all__ = ["Array", "GeosynError", "InvalidArgument", "Matrix", "Vector"]
