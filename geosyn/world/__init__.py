"""World geometry: solid shapes and their poses, signed distances, and payloads.

`Sphere`, `Box` (oriented), `Capsule`, `Cylinder` and `HalfSpace` are validated once here
(`geosyn.world.validation`, one set of tolerances) and used alike by the obstacle shaping
term, the simulation scene and the experiments; `signed_distance` (numpy) and
`rounded_box_distance` (CasADi) measure them exactly, `geosyn.world.smooth` smoothly
(C-infinity, conservative, stated error); `load_mjcf_obstacles` reads them from the
static geoms of a MuJoCo scene file. A `Payload` (mass, centre of mass, inertia,
carrying frame) describes a held object for the load term, the test plant and the scene.
"""

if not __name__.startswith("geosyn."):  # the folder imported as a top-level package
    raise ImportError(f"import geosyn.world, not {__name__}: one module, one name")


from geosyn.world.distance import signed_distance
from geosyn.world.errors import InvalidGeometry, WorldError
from geosyn.world.mjcf_scene import MjcfObstacles, load_mjcf_obstacles
from geosyn.world.payload import Payload
from geosyn.world.pose import rotation_from_rpy
from geosyn.world.shapes import (
    HALFSPACE_EXTENT,
    Box,
    Capsule,
    Cylinder,
    HalfSpace,
    Shape,
    Sphere,
)
from geosyn.world.smooth import smooth_signed_distance

__all__ = [
    "HALFSPACE_EXTENT",
    "Box",
    "Capsule",
    "Cylinder",
    "HalfSpace",
    "InvalidGeometry",
    "MjcfObstacles",
    "Payload",
    "Shape",
    "Sphere",
    "WorldError",
    "rotation_from_rpy",
    "load_mjcf_obstacles",
    "signed_distance",
    "smooth_signed_distance",
]
