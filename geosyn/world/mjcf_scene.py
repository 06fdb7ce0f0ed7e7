"""Obstacles from a MuJoCo scene file: the static geoms of an MJCF model as world shapes.

MuJoCo compiles the file (includes, defaults, ``fromto``, any orientation convention), and
each geom welded to the world body (``body_weldid == 0``: in the worldbody or in bodies
without joints) becomes one shape at its compiled world pose:

=============  =========================================================
MuJoCo geom    shape
=============  =========================================================
``plane``      `HalfSpace` (free side along the geom's z axis)
``sphere``     `Sphere`
``capsule``    `Capsule` (segment along the geom's z axis)
``cylinder``   `Cylinder`
``box``        `Box`
``ellipsoid``  `Box` enclosing it (reported in ``approximated``)
``mesh``       `Box`: the mesh's bounding box in the geom frame (reported)
=============  =========================================================

Geoms of moving bodies are skipped, and so are purely visual geoms (``contype`` and
``conaffinity`` both 0) unless ``visual=True``; every skipped or approximated geom is listed
in the result, nothing is dropped silently.
"""

from __future__ import annotations

import os
from typing import NamedTuple

import numpy as np

from geosyn.world import shapes
from geosyn.world.errors import InvalidGeometry

__all__ = ["MjcfObstacles", "load_mjcf_obstacles"]


class MjcfObstacles(NamedTuple):
    """The static geoms of an MJCF scene as shapes.

    Attributes:
        shapes: the shapes, in geom order.
        names: the geom name of each shape (``"geom<i>"`` for an unnamed geom).
        approximated: ``"name: how"`` for each shape that encloses its geom.
        skipped: ``"name: why"`` for each geom left out.
        moving: the names of the geoms left out because they are on a moving body (a
            robot in the file, say; also in ``skipped``).
    """

    shapes: tuple[shapes.Shape, ...]
    names: tuple[str, ...]
    approximated: tuple[str, ...]
    skipped: tuple[str, ...]
    moving: tuple[str, ...] = ()


def _geom_name(model: object, i: int) -> str:
    import mujoco

    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, i)
    return name if name else f"geom{i}"


def load_mjcf_obstacles(source: str | os.PathLike[str], *, visual: bool = False) -> MjcfObstacles:
    """Read the static geoms of a MuJoCo scene file (or XML string) as shapes.

    Args:
        source: path of an MJCF file, or the XML text itself (starting with ``<``).
        visual: also take purely visual geoms (``contype = conaffinity = 0``).

    Returns:
        The shapes and what was skipped or approximated.

    Raises:
        InvalidGeometry: MuJoCo cannot load the file.
    """
    import mujoco

    text = str(source)
    try:
        if text.lstrip().startswith("<"):
            model = mujoco.MjModel.from_xml_string(text)
        else:
            model = mujoco.MjModel.from_xml_path(os.fspath(source))
    except (ValueError, FileNotFoundError) as err:
        raise InvalidGeometry(
            f"source: MuJoCo could not load it: {err}", "source", text[:80]
        ) from err
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    T = mujoco.mjtGeom
    out: list[shapes.Shape] = []
    names: list[str] = []
    approx: list[str] = []
    skipped: list[str] = []
    moving: list[str] = []
    for i in range(model.ngeom):
        name = _geom_name(model, i)
        body = int(model.geom_bodyid[i])
        if int(model.body_weldid[body]) != 0:
            skipped.append(f"{name}: on a moving body")
            moving.append(name)
            continue
        if not visual and model.geom_contype[i] == 0 and model.geom_conaffinity[i] == 0:
            skipped.append(f"{name}: visual only (contype = conaffinity = 0)")
            continue
        kind = int(model.geom_type[i])
        size = np.asarray(model.geom_size[i], dtype=float)
        pos = np.asarray(data.geom_xpos[i], dtype=float)
        R = np.asarray(data.geom_xmat[i], dtype=float).reshape(3, 3)
        shape: shapes.Shape
        if kind == T.mjGEOM_PLANE:
            n = R[:, 2]
            shape = shapes.HalfSpace(n, float(n @ pos))  # type: ignore[arg-type]
        elif kind == T.mjGEOM_SPHERE:
            shape = shapes.Sphere(pos, float(size[0]))  # type: ignore[arg-type]
        elif kind == T.mjGEOM_CAPSULE:
            a = R[:, 2] * size[1]
            shape = shapes.Capsule(pos - a, pos + a, float(size[0]))
        elif kind == T.mjGEOM_CYLINDER:
            shape = shapes.Cylinder(pos, float(size[0]), float(size[1]), R)  # type: ignore[arg-type]
        elif kind == T.mjGEOM_BOX:
            shape = shapes.Box(pos, size, R)  # type: ignore[arg-type]
        elif kind == T.mjGEOM_ELLIPSOID:
            shape = shapes.Box(pos, size, R)  # type: ignore[arg-type]
            approx.append(f"{name}: ellipsoid -> its enclosing box")
        elif kind == T.mjGEOM_MESH:
            aabb = np.asarray(model.geom_aabb[i], dtype=float)  # centre (3), half sizes (3)
            shape = shapes.Box(pos + R @ aabb[:3], aabb[3:], R)  # type: ignore[arg-type]
            approx.append(f"{name}: mesh -> its bounding box in the geom frame")
        else:
            skipped.append(f"{name}: geom type {kind} has no shape")
            continue
        out.append(shape)
        names.append(name)
    return MjcfObstacles(tuple(out), tuple(names), tuple(approx), tuple(skipped),
                         tuple(moving))  # fmt: skip
