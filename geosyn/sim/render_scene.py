"""What a video frame is drawn from: the robot's own meshes where its model file has them,
geosyn's scene (floor, payloads, obstacles, capsules otherwise), and the decorations
(path lines, force arrows).

`FrameScene` holds two MuJoCo models posed at the same configuration:

- geosyn's scene (`geosyn.sim.scene.build_scene`): floor, sky, payloads, obstacles, and the
  robot's collision capsules;
- the robot's own file, when it has one MuJoCo can draw: an MJCF file as it is (meshes,
  materials), or a URDF compiled by MuJoCo with its collision meshes (MuJoCo reads STL/OBJ
  meshes, not the COLLADA visuals; ``package://`` paths are resolved to the robot's
  package directory). It replaces the capsules only if it poses like the simulated model:
  every controlled joint's anchor within `MESH_TOLERANCE` of Pinocchio's at a test
  configuration; otherwise the capsules are drawn and `mesh_note` says why.

A run whose plant was the robot's ORIGINAL MJCF file (``Simulation(plant="file")``,
`geosyn.sim.file_scene`) is drawn from that file whatever it holds (meshes or primitive
geoms; ``plant="file"``): it is what was simulated, so no pose check is made and no
capsule stands in for it. Joints of the file that the robot does not control (passive in
that simulation, not logged) are drawn at the file's reference configuration ``qpos0``.

`Marker` is a ball drawn at a point that may move (a target the robot reaches).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple

import mujoco
import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_choice
from geosyn.robots.robot import Robot
from geosyn.sim.scene import Scene, build_scene
from geosyn.world import Payload

#: Largest distance [m] between a joint anchor of the robot's file and of the simulated
#: model (at a test configuration) for the file's meshes to be drawn.
MESH_TOLERANCE = 1e-3
#: A model file with more geoms than this is drawn without shadows (they double the time
#: of a frame in software rendering: TALOS, 53 geoms, ~0.45 -> ~0.22 s at 640 x 480).
SHADOW_MAX_GEOMS = 30
#: Group the capsules are moved to when meshes replace them (not drawn).
_HIDDEN_GROUP = 5
#: Name of the floor geosyn adds to a model file it draws (not added when the file has a
#: plane of its own in its world body: that one is part of the model and is not moved).
FILE_FLOOR = "geosyn_floor"


def _urdf_for_mujoco(path: Path) -> str:
    """A URDF's text with ``package://`` mesh paths made absolute and MuJoCo's compiler
    told to keep them (``strippath="false"``), its collision meshes drawn."""
    text = path.read_text()

    def resolve(match: re.Match[str]) -> str:
        rel = match.group(1)
        for parent in path.parents:  # the package directory is an ancestor of the file
            if (parent / rel).is_file():
                return str(parent / rel)
            head, _, rest = rel.partition("/")
            if (parent / rest).is_file() and parent.name == head:
                return str(parent / rest)
        return match.group(0)

    text = re.sub(r"package://([^\"']+)", resolve, text)
    options = '<mujoco><compiler strippath="false" discardvisual="true"/></mujoco>'
    return re.sub(r"(<robot\b[^>]*>)", r"\1" + options, text, count=1)


def _decorate(spec: mujoco.MjSpec) -> None:
    """Add geosyn's sky, overhead light and floor to a model file's spec (as in `build_scene`;
    no floor when the file has a plane of its own)."""
    spec.add_texture(
        name="geosyn_sky",
        type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
        builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
        rgb1=[0.93, 0.95, 0.98],
        rgb2=[0.62, 0.7, 0.8],
        width=64,
        height=64,
    )
    light = spec.worldbody.add_light(name="geosyn_light", pos=[0.0, 0.0, 4.0], dir=[0.0, 0.0, -1.0])
    light.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
    light.castshadow = True
    if any(g.type == mujoco.mjtGeom.mjGEOM_PLANE for g in spec.worldbody.geoms):
        return
    floor = spec.worldbody.add_geom(
        name=FILE_FLOOR,
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[3.0, 3.0, 0.1],
        pos=[0.0, 0.0, -0.01],
        rgba=[0.9, 0.9, 0.9, 1.0],
    )
    floor.contype = floor.conaffinity = 0


def _decorate_xml(xml: str) -> str:
    """MJCF text with geosyn's sky, overhead light and floor added (as in `build_scene`)."""
    sky = (
        '<asset><texture name="geosyn_sky" type="skybox" builtin="gradient"'
        ' rgb1="0.93 0.95 0.98" rgb2="0.62 0.7 0.8" width="64" height="64"/></asset>'
    )
    light = (
        '<light name="geosyn_light" pos="0 0 4" dir="0 0 -1" directional="true"/>'
        f'<geom name="{FILE_FLOOR}" type="plane" size="3 3 0.1" pos="0 0 -0.01" rgba="0.9 0.9 0.9 1"'
        ' contype="0" conaffinity="0"/>'
    )
    xml = re.sub(r"(<mujoco\b[^>]*>)", r"\1" + sky, xml, count=1)
    return re.sub(r"(<worldbody>)", r"\1" + light, xml, count=1)


def _file_model(robot: Robot, plant: bool = False) -> tuple[mujoco.MjModel | None, str]:
    """The robot's own file compiled by MuJoCo, or None and the reason.

    With ``plant`` (the file was the simulated plant) a file without meshes is drawn too
    (its primitive geoms), and a file that does not compile is an error.

    Raises:
        InvalidArgument: ``plant`` and the robot has no MJCF file, or it does not compile.
    """
    source = getattr(robot, "source_file", None)
    if plant and (source is None or Path(source).suffix.lower() not in (".xml", ".mjcf")):
        raise InvalidArgument(
            f"plant='file' draws the robot's MJCF file, but robot {robot.name!r} comes from"
            f" {source or 'code (a built-in)'}: use plant='model'"
        )
    if source is None:
        return None, "the robot has no model file (built in code)"
    path = Path(source)
    try:
        if path.suffix.lower() == ".urdf":
            # via MJCF text: a URDF's spec drops added assets (the sky) when compiled
            xml = mujoco.MjSpec.from_string(_urdf_for_mujoco(path)).to_xml()
            model = mujoco.MjModel.from_xml_string(_decorate_xml(xml))
        else:
            spec = mujoco.MjSpec.from_file(str(path))
            _decorate(spec)
            model = spec.compile()
    except (ValueError, OSError) as err:
        if plant:
            raise InvalidArgument(f"the file plant {str(path)!r} does not compile: {err}") from err
        return None, f"MuJoCo cannot compile {path.name} for drawing: {err}"
    if model.nmesh == 0 and not plant:
        return None, f"{path.name} has no meshes MuJoCo can read"
    return model, ""


def _joint_qpos(model: mujoco.MjModel, robot: Robot) -> np.ndarray | None:
    """(nq,) qpos address in ``model`` of each joint of the robot, or None if one is missing."""
    adr = []
    for name in robot.joint_names:
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0:
            return None
        adr.append(int(model.jnt_qposadr[jid]))
    return np.array(adr, dtype=np.int64)


def _poses_alike(robot: Robot, model: mujoco.MjModel, adr: np.ndarray) -> float:
    """Largest distance [m] between the joint anchors of ``model`` and Pinocchio's at a
    fixed test configuration (inside the limits)."""
    q = robot.neutral() + 0.3 * np.sin(np.arange(1, robot.nq + 1))
    lo, hi = robot.q_min, robot.q_max
    q = np.where(np.isfinite(lo) & np.isfinite(hi), np.clip(q, lo, hi), q)
    data = mujoco.MjData(model)
    data.qpos[adr] = q
    mujoco.mj_kinematics(model, data)
    pdata = robot.model.createData()
    pin.forwardKinematics(robot.model, pdata, q)
    err = 0.0
    for name in robot.joint_names:
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        pj = pdata.oMi[robot.model.getJointId(name)].translation
        err = max(err, float(np.linalg.norm(data.xanchor[jid] - pj)))
    return err


class FrameScene:
    """The models of a video frame, posed together (see the module doc).

    Args:
        robot: the robot.
        payloads: payloads drawn.
        obstacles: obstacles drawn.
        meshes: draw the robot's own meshes where its file has them.
        plant: ``model`` (default): the run simulated geosyn's rebuilt model (the file's
            meshes replace its capsules as above); ``file``: the run simulated the robot's
            original MJCF file (``Simulation(plant="file")``), which is drawn as it is
            (meshes or primitive geoms; ``meshes`` is then not consulted).

    Attributes:
        scene: geosyn's scene (names resolve here: bodies for force arrows).
        data: its data (kinematics at the posed configuration).
        model: the model the renderer is built for (the file's when it is drawn).
        mesh_note: why the capsules are drawn ("" when the file is).
        plant: the ``plant`` argument.

    Raises:
        InvalidArgument: an unknown ``plant``; ``plant="file"`` for a robot without an
            MJCF file or whose file does not compile.
    """

    def __init__(
        self,
        robot: Robot,
        payloads: Sequence[Payload] = (),
        obstacles: Sequence[Any] = (),
        meshes: bool = True,
        plant: str = "model",
    ) -> None:
        self.plant = check_choice(plant, ("model", "file"), "plant")
        self.robot = robot
        self.scene: Scene = build_scene(robot, payloads=payloads, obstacles=obstacles, decor=True)
        self.data = mujoco.MjData(self.scene.model)
        self.option = mujoco.MjvOption()
        self.option.geomgroup[:] = (1, 1, 1, 0, 0, 0)  # floor, robot/payloads, obstacles
        self._file: mujoco.MjModel | None = None
        self._file_data: mujoco.MjData | None = None
        self._file_adr: np.ndarray | None = None
        self._perturb = mujoco.MjvPerturb()
        self.mesh_note = "meshes not requested"
        if meshes or self.plant == "file":
            self.mesh_note = self._use_file()
        self.model = self._file if self._file is not None else self.scene.model

    @property
    def drawn_as(self) -> str:
        """What the robot is drawn with, in words (for run records)."""
        if self.plant == "file" and self._file is not None:
            name = Path(str(self.robot.source_file)).name
            what = "its meshes" if self._file.nmesh else "its geoms"
            return f"the simulated plant: its original file {name} ({what})"
        return f"collision capsules ({self.mesh_note})" if self.mesh_note else "its own meshes"

    def _use_file(self) -> str:
        plant = self.plant == "file"
        model, note = _file_model(self.robot, plant)
        if model is None:
            return note
        adr = _joint_qpos(model, self.robot)
        if adr is None:
            if plant:  # Simulation(plant="file") refuses such a file first
                raise InvalidArgument(
                    f"the file plant {self.robot.source_file!r} lacks joints of robot"
                    f" {self.robot.name!r}"
                )
            return "the model file lacks some of the robot's joints"
        # The file plant is what was simulated: it is drawn without a pose check.
        err = 0.0 if plant else _poses_alike(self.robot, model, adr)
        if err > MESH_TOLERANCE:
            return f"the model file poses {err:.3g} m away from the simulated model"
        geo = self.scene.model
        payload_bodies = set(int(b) for b in self.scene.payload_body_ids)
        floor = mujoco.mj_name2id(geo, mujoco.mjtObj.mjOBJ_GEOM, "floor")
        for g in range(geo.ngeom):  # hide the capsules (robot bodies' geoms, not payloads)
            body = int(geo.geom_bodyid[g])
            if (body != 0 and body not in payload_bodies) or g == floor:
                geo.geom_group[g] = _HIDDEN_GROUP  # the file model draws its own floor
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, geo.vis.global_.offwidth)
        model.vis.global_.offheight = max(model.vis.global_.offheight, geo.vis.global_.offheight)
        model.vis.quality.shadowsize = geo.vis.quality.shadowsize
        if model.ngeom > SHADOW_MAX_GEOMS:  # shadows double the cost of a frame
            model.light_castshadow[:] = 0
        self._file, self._file_data, self._file_adr = model, mujoco.MjData(model), adr
        return ""

    def lowest_point(self, q: np.ndarray) -> float:
        """Lowest point [m] (z) of the drawn robot at ``q`` (nq,) [rad], from the geoms'
        bounding spheres; the floor goes below it."""
        self.pose(q)
        low = np.inf
        for model, data in self.posed_models():
            shown = (model.geom_group <= 2) & (model.geom_type != mujoco.mjtGeom.mjGEOM_PLANE)
            shown &= model.geom_bodyid != 0
            if shown.any():
                low = min(low, float(np.min(data.geom_xpos[shown, 2] - model.geom_rbound[shown])))
        return low

    @property
    def has_meshes(self) -> bool:
        """Whether the robot's own file is drawn (its meshes; with ``plant="file"`` also a
        file of primitive geoms)."""
        return self._file is not None

    def floors(self) -> list[tuple[mujoco.MjModel, int]]:
        """(model, geom id) of the floors geosyn added (lowered under the robot by a
        video); a plane of the robot's own file is not one of them."""
        out = []
        for model, name in ((self.scene.model, "floor"), (self._file, FILE_FLOOR)):
            if model is not None:
                gid = int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name))
                if gid >= 0:
                    out.append((model, gid))
        return out

    def pose(self, q: np.ndarray) -> None:
        """Set both models to configuration ``q`` (nq,) [rad] (positions, lights)."""
        for model, data, adr in self._posed():
            data.qpos[adr] = q
            mujoco.mj_kinematics(model, data)  # positions only: no dynamics needed
            mujoco.mj_comPos(model, data)
            mujoco.mj_camlight(model, data)  # lights that follow bodies

    def posed_models(self) -> list[tuple[mujoco.MjModel, mujoco.MjData]]:
        """(model, data) of geosyn's scene, then of the robot's file when its meshes are
        drawn: what `pose` moves. Geoms of groups 0-2 are the visible ones (the capsules
        are in group 5 when the file's meshes replace them)."""
        return [(model, data) for model, data, _ in self._posed()]

    def _posed(self) -> list[tuple[mujoco.MjModel, mujoco.MjData, np.ndarray]]:
        out = [(self.scene.model, self.data, self.scene.qpos_adr)]
        if self._file is not None and self._file_data is not None and self._file_adr is not None:
            out.append((self._file, self._file_data, self._file_adr))
        return out

    def update(self, scn: mujoco.MjvScene, camera: mujoco.MjvCamera) -> None:
        """Fill ``scn`` with the posed geoms: the file's, then geosyn's visible ones."""
        cat = mujoco.mjtCatBit.mjCAT_ALL.value
        if self._file is None:
            mujoco.mjv_updateScene(self.scene.model, self.data, self.option, None, camera, cat, scn)
            return
        mujoco.mjv_updateScene(
            self._file, self._file_data, mujoco.MjvOption(), None, camera, cat, scn
        )
        mujoco.mjv_addGeoms(self.scene.model, self.data, self.option, self._perturb, cat, scn)


class Marker(NamedTuple):
    """A ball drawn in a video at a point that may move (e.g. a target the robot reaches).

    Attributes:
        t: (K,) increasing time stamps [s] (one stamp: a fixed point).
        position: (K, 3) its centre at those times [m]; linear in between, held outside.
        radius: its radius [m].
        rgba: its colour (4 floats in [0, 1]).
    """

    t: np.ndarray
    position: np.ndarray
    radius: float = 0.02
    rgba: tuple[float, float, float, float] = (0.1, 0.85, 0.1, 1.0)

    def checked(self) -> Marker:
        """This marker with float64 arrays, checked.

        Raises:
            InvalidArgument: shapes that do not match, unordered times, a radius <= 0.
        """
        t = np.atleast_1d(np.asarray(self.t, dtype=np.float64))
        pos = np.asarray(self.position, dtype=np.float64).reshape(-1, 3)
        ok = t.ndim == 1 and len(t) >= 1 and pos.shape == (len(t), 3)
        if not ok or not np.all(np.isfinite(pos)) or np.any(np.diff(t) <= 0.0):
            raise InvalidArgument(
                "marker must have increasing t (K,) [s] and finite position (K, 3) [m],"
                f" got t {t.shape}, position {np.shape(self.position)}"
            )
        if not float(self.radius) > 0.0:
            raise InvalidArgument(f"marker radius must be > 0 [m], got {self.radius!r}")
        if len(self.rgba) != 4:
            raise InvalidArgument(f"marker rgba must be 4 floats in [0, 1], got {self.rgba!r}")
        r, g, b, a = (float(c) for c in self.rgba)
        return Marker(t, pos, float(self.radius), (r, g, b, a))

    def at(self, time: float) -> np.ndarray:
        """(3,) centre [m] at ``time`` [s]."""
        return np.array([np.interp(time, self.t, self.position[:, i]) for i in range(3)])


def add_sphere(scn: mujoco.MjvScene, center: np.ndarray, radius: float, rgba: Any) -> None:
    """Append a visual-only ball of ``radius`` [m] at ``center`` (3,) [m] (ignored when the
    scene is full)."""
    if scn.ngeom >= scn.maxgeom:
        return
    mujoco.mjv_initGeom(
        scn.geoms[scn.ngeom],
        mujoco.mjtGeom.mjGEOM_SPHERE,
        np.full(3, float(radius)),
        np.asarray(center, dtype=np.float64),
        np.eye(3).ravel(),
        np.asarray(rgba, np.float32),
    )
    scn.ngeom += 1


def point_in_body(scene: Scene, d: Any) -> np.ndarray | None:
    """(3,) point of application of a push/wrench in its MuJoCo body's frame [m], or None
    (the body's centre of mass)."""
    point = getattr(d, "point", None)
    return None if point is None else scene.frame_point_in_body(d.body, point)


def add_connector(
    scn: mujoco.MjvScene, kind: int, width: float, p0: np.ndarray, p1: np.ndarray, rgba: Any
) -> None:
    """Append a visual-only line or arrow from p0 to p1 [m] (ignored when the scene is full)."""
    if scn.ngeom >= scn.maxgeom:
        return
    geom = scn.geoms[scn.ngeom]
    mujoco.mjv_initGeom(
        geom, kind, np.zeros(3), np.zeros(3), np.eye(3).ravel(), np.asarray(rgba, np.float32)
    )
    mujoco.mjv_connector(geom, kind, width, np.asarray(p0, np.float64), np.asarray(p1, np.float64))
    geom.category = mujoco.mjtCatBit.mjCAT_DECOR  # casts no shadow
    scn.ngeom += 1


def add_polyline(scn: mujoco.MjvScene, points: np.ndarray, rgba: Any, width: float) -> None:
    """Append a line through ``points`` (N, 3) [m], ``width`` [px] wide."""
    for a, b in zip(points[:-1], points[1:], strict=True):
        add_connector(scn, mujoco.mjtGeom.mjGEOM_LINE, width, a, b, rgba)


def force_now(d: Any, t: float) -> np.ndarray | None:
    """(3,) force [N] a push or wrench applies at ``t`` [s], or None (not acting, no force)."""
    force = getattr(d, "force", None)
    if force is None:
        return None
    if hasattr(d, "active"):
        scale = 1.0 if d.active(t) else 0.0
    elif hasattr(d, "scale"):
        scale = float(d.scale(t))
    else:
        return None
    f = scale * np.asarray(force, dtype=np.float64)
    return f if np.linalg.norm(f) > 0.0 else None


__all__ = [
    "FILE_FLOOR",
    "MESH_TOLERANCE",
    "SHADOW_MAX_GEOMS",
    "FrameScene",
    "Marker",
    "add_connector",
    "add_polyline",
    "add_sphere",
    "force_now",
    "point_in_body",
]
