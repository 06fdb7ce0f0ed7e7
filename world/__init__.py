"""World geometry: solid shapes and their poses, signed distances, and payloads.

`Sphere`, `Box` (oriented), `Capsule` and `HalfSpace` are validated once here
(`geosyn.world.validation`, one set of tolerances) and used alike by the obstacle shaping
term, the simulation scene and the experiments; `signed_distance` (numpy) and
`rounded_box_distance` (CasADi) measure them. A `Payload` (mass, centre of mass, inertia,
carrying frame) describes a held object for the load term, the test plant and the scene.
"""

if not __name__.startswith("geosyn."):  # the folder imported as a top-level package
    raise ImportError(f"import geosyn.world, not {__name__}: one module, one name")


from geosyn.world.distance import signed_distance
from geosyn.world.errors import InvalidGeometry, WorldError
from geosyn.world.payload import Payload
from geosyn.world.pose import rotation_from_rpy
from geosyn.world.shapes import HALFSPACE_EXTENT, Box, Capsule, HalfSpace, Shape, Sphere

__all__ = [
    "HALFSPACE_EXTENT",
    "Box",
    "Capsule",
    "HalfSpace",
    "InvalidGeometry",
    "Payload",
    "Shape",
    "Sphere",
    "WorldError",
    "rotation_from_rpy",
    "signed_distance",
]
