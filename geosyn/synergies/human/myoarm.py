"""The human right arm (MyoArm of ``myo-sim``) as a geosyn `Robot`, with its muscles listed.

What geosyn models: the arm's rigid-body skeleton (MuJoCo's compile of the published MJCF:
bone masses and inertias, joint anchors, axes and ranges, armature), its 11 linear joint
equalities as ``robot.coupling`` (q = S z + c; the shoulder girdle follows
``shoulder_elv_r``, ``shoulder1_r2_r`` follows ``elv_angle_r``), joint-space dynamics
M(q), c(q, v), g(q) and joint torques. What it does not model: the 63 muscles (Hill-type
activation and force-length-velocity dynamics), the 67 tendons (their paths, wrapping,
limits), joint damping and passive stiffness of the file. The muscles are reported
(`MuscleInfo`: peak isometric force, spanned joints and moment arms at the reference
posture) and their summed capacity ``sum_m |r_mj| F_max,m`` at the reference posture is
used as each joint's torque limit (labelled so in ``Robot.tau_max_source``): an upper
bound of what the muscles could produce there, not a muscle model.

The published arm pieces (chain, assets, tendons, muscles) are not a standalone file:
some tendons run over the thorax. `myoarm_xml` writes a small wrapper next to them that
places the arm on a fixed ``chest_r`` frame with the thorax sites and wrapping spheres
copied from myo-sim's torso chain, at the pose myo-sim's own composition gives (the
torso's reference posture).
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import NamedTuple

import mujoco
import numpy as np

from geosyn.robots import Robot
from geosyn.robots.files import load_file
from geosyn.robots.from_mjcf import pinocchio_from_mjmodel
from geosyn.robots.from_model import robot_from_model
from geosyn.synergies.human.data import MYO_SIM, Provenance, extract

ARM_COORDINATES: tuple[str, ...] = (
    "elv_angle_r",
    "shoulder_elv_r",
    "shoulder_rot_r",
    "elbow_flexion_r",
    "pro_sup_r",
    "deviation_r",
    "flexion_r",
)
"""The 7 independent coordinates z of the arm (shoulder, elbow, forearm, wrist)."""

GIRDLE_JOINTS: tuple[str, ...] = (
    "sternoclavicular_r2_r",
    "sternoclavicular_r3_r",
    "unrotscap_r3_r",
    "unrotscap_r2_r",
    "acromioclavicular_r2_r",
    "acromioclavicular_r3_r",
    "acromioclavicular_r1_r",
    "unrothum_r1_r",
    "unrothum_r3_r",
    "unrothum_r2_r",
    "shoulder1_r2_r",
)
"""The 11 joints the file's equalities make dependent."""

KEYPOINT_FRAMES: dict[str, str] = {
    "RightShoulder": "clavicle_r",  # sternoclavicular joint (fixed on the thorax)
    "RightArm": "humphant_r",  # glenohumeral joint centre
    "RightForeArm": "ulna_r",  # elbow
    "RightHand": "lunate_r",  # wrist
    "RightHandIndex1": "2proxph_r",  # metacarpophalangeal joints
    "RightHandMiddle1": "3proxph_r",
    "RightHandPinky1": "5proxph_r",
}
"""Capture joint -> MyoArm body whose origin is the same anatomical point."""

SEGMENTS: dict[str, tuple[str, str]] = {
    "shoulder": ("RightShoulder", "RightArm"),
    "upper_arm": ("RightArm", "RightForeArm"),
    "forearm": ("RightForeArm", "RightHand"),
    "hand": ("RightHand", "RightHandMiddle1"),
}
"""Segments scaled independently, each by its end keypoints."""

_SEGMENT_ROOTS = {"clavicle_r": "shoulder", "humphant_r": "upper_arm", "ulna_r": "forearm"}
_SEGMENT_ROOTS["lunate_r"] = "hand"
_CHEST_TO_CLAVICLE = (-0.03634 + 0.044675, 0.025 - 0.01807, 0.025465)
"""Clavicle origin in the chest frame [m]: cervical_spine's offset plus its arm_attach_r
site in myo-sim's torso chain (both without rotation)."""

MODELLING = (
    "geosyn models the arm's rigid skeleton (joint-space M(q), c, g, joint torques) with"
    " the file's 11 linear joint equalities as q = S z + c; it does not model the muscles'"
    " activation and force-length-velocity dynamics, the tendon paths, joint damping or"
    " passive stiffness. Joint torque limits are the muscles' summed capacity"
    " sum |moment arm| x F_max at the reference posture, an upper bound."
)


class MuscleInfo(NamedTuple):
    """One muscle of the file, as geosyn reports it (not modelled)."""

    name: str
    tendon: str  # the tendon it pulls
    f_max: float  # peak isometric force [N]
    moment_arms: dict[str, float]  # joint -> moment arm at the reference posture [m]


class HumanArm(NamedTuple):
    """The MyoArm as a geosyn robot, with what was left out stated."""

    robot: Robot  # girdle + 7 arm coordinates, fingers locked at qpos0 (or all 38 joints)
    muscles: tuple[MuscleInfo, ...]  # (63,)
    scale: dict[str, float]  # segment -> length factor applied (1.0 unscaled)
    modelling: str  # what geosyn models and what it does not
    provenance: Provenance


def _chest_items(torso_chain: Path, needed: set[str]) -> list[ET.Element]:
    """Sites and wrapping geoms of the torso's chest_r body that the arm's tendons use."""
    root = ET.parse(torso_chain).getroot()
    chest = next(b for b in root.iter("body") if b.get("name") == "chest_r")
    items = []
    for child in chest:
        if child.tag in ("site", "geom") and child.get("name") in needed:
            item = ET.Element(child.tag, {k: v for k, v in child.attrib.items() if k != "class"})
            if child.tag == "geom":
                item.attrib.update(group="3", contype="0", conaffinity="0", mass="0")
            items.append(item)
    return items


def myoarm_xml(cache: Path | None = None, *, muscles: bool = True) -> tuple[Path, Provenance]:
    """The MyoArm MJCF wrapper (written once into the extracted myo-sim folder).

    Args:
        cache: data cache folder.
        muscles: include the tendons and the 63 muscles (else the skeleton only).

    Returns:
        The file and the provenance of the myo-sim wheel.
    """
    root, prov = extract(
        MYO_SIM,
        lambda n: (
            n.startswith("myo_sim/models/")
            and ("/arm/" in n or "/meshes/" in n or n.endswith("torso/assets/myotorso_chain.xml"))
        ),
        cache,
    )
    arm = root / "myo_sim" / "models" / "arm"
    out = arm / f"geosyn_myoarm_r{'' if muscles else '_skeleton'}.xml"
    if out.is_file():
        return out, prov
    tendons = (arm / "assets" / "myoarm_r_tendon.xml").read_text()
    needed = {
        str(e.get(k))
        for e in ET.fromstring(tendons).iter()
        for k in ("site", "geom", "sidesite")
        if e.get(k)
    }
    torso = root / "myo_sim" / "models" / "torso" / "assets" / "myotorso_chain.xml"
    chest = "".join(ET.tostring(e, encoding="unicode") for e in _chest_items(torso, needed))
    offset = " ".join(f"{x:.6g}" for x in _CHEST_TO_CLAVICLE)
    rest = (
        '<include file="assets/myoarm_r_tendon.xml"/><include file="assets/myoarm_r_muscle.xml"/>'
        if muscles
        else ""
    )
    out.write_text(
        '<mujoco model="myoarm_r">\n<include file="assets/myoarm_r_assets.xml"/>\n'
        '<compiler angle="radian" meshdir=".." texturedir=".."/>\n<worldbody>\n'
        '<body name="sacrum_frame" euler="1.57079632679 -1.57079632679 0">\n'
        '<body name="arm_attachment" euler="-1.57079632679 0 1.57079632679">\n'
        f'<body name="chest_r" euler="1.57079632679 -1.57079632679 0">{chest}\n'
        f'<body name="arm_root_r" pos="{offset}">\n'
        '<include file="assets/myoarm_r_chain.xml"/>\n'
        f"</body></body></body></body>\n</worldbody>\n{rest}\n</mujoco>\n"
    )
    return out, prov


def muscles_of(m: mujoco.MjModel) -> tuple[MuscleInfo, ...]:
    """The muscles of a compiled model with their moment arms at ``qpos0``."""
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    moment = np.zeros((m.nu, m.nv))
    mujoco.mju_sparse2dense(
        moment, d.actuator_moment, d.moment_rownnz, d.moment_rowadr, d.moment_colind
    )
    joint_of_dof = [
        mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, int(m.dof_jntid[i])) for i in range(m.nv)
    ]
    out = []
    for a in range(m.nu):
        if m.actuator_trntype[a] != int(mujoco.mjtTrn.mjTRN_TENDON):
            continue
        tendon = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_TENDON, int(m.actuator_trnid[a, 0]))
        arms = {str(joint_of_dof[i]): float(moment[a, i]) for i in np.flatnonzero(moment[a])}
        out.append(
            MuscleInfo(
                str(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a)),
                str(tendon),
                float(m.actuator_gainprm[a, 2]),
                arms,
            )
        )
    return tuple(out)


def _scale_compiled(m: mujoco.MjModel, scale: dict[str, float]) -> None:
    """Scale segment lengths of a compiled model in place (masses kept, inertias ~ s^2)."""
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(m.nbody)]
    factor = np.ones(m.nbody)
    for b in range(1, m.nbody):
        parent = int(m.body_parentid[b])
        seg = _SEGMENT_ROOTS.get(str(names[b]))
        factor[b] = scale.get(seg, 1.0) if seg else factor[parent]
        m.body_pos[b] *= factor[parent] if parent else 1.0
        m.body_ipos[b] *= factor[b]
        m.body_inertia[b] *= factor[b] ** 2
    for j in range(m.njnt):
        m.jnt_pos[j] *= factor[m.jnt_bodyid[j]]
    for s in range(m.nsite):
        m.site_pos[s] *= factor[m.site_bodyid[s]]


def load_myoarm(
    cache: Path | None = None, scale: dict[str, float] | None = None, *, fingers: bool = False
) -> HumanArm:
    """The MyoArm as a `Robot` of its arm joints (fingers locked at the file's qpos0).

    Args:
        cache: data cache folder.
        fingers: keep all 38 joints (27 independent coordinates, the 20 hand joints
            included) instead of locking the fingers (18 joints, 7 coordinates).
        scale: ``{segment: length factor}`` for segments of `SEGMENTS` (``None``: the
            published 50th-percentile model). Positions inside a segment scale by its
            factor, masses stay, inertias scale by its square.

    Returns:
        The arm, its muscles and the modelling statement.
    """
    path, prov = myoarm_xml(cache, muscles=True)
    full = mujoco.MjModel.from_xml_path(str(path))
    muscles = muscles_of(full)
    capacity: dict[str, float] = {}
    for mus in muscles:
        for joint, r in mus.moment_arms.items():
            capacity[joint] = capacity.get(joint, 0.0) + abs(r) * mus.f_max
    names = [mujoco.mj_id2name(full, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(full.njnt)]
    keep = [str(n) for n in names] if fingers else [*GIRDLE_JOINTS, *ARM_COORDINATES]
    tau = {j: capacity[j] for j in keep if capacity.get(j, 0.0) > 0}
    source = "muscles: sum |moment arm| x F_max at qpos0 (upper bound; muscles not modelled)"
    factors = {s: float((scale or {}).get(s, 1.0)) for s in SEGMENTS}
    if scale is None:
        robot = load_file(path, keep_joints=keep, name="myoarm_r", tau_max=tau)
    else:
        skeleton, _ = myoarm_xml(cache, muscles=False)
        m = mujoco.MjModel.from_xml_path(str(skeleton))
        _scale_compiled(m, factors)
        read = pinocchio_from_mjmodel(m, path=skeleton)
        robot = robot_from_model(
            read.model,
            name="myoarm_r_scaled",
            keep_joints=keep,
            tau_max=tau,
            file_tau_max=read.tau_max,
            damping=read.damping,
            frictionloss=read.frictionloss,
            couplings=read.couplings,
            source_file=str(skeleton),
        )
    sources = tuple(source if s == "user" else s for s in robot.tau_max_source)
    robot = dataclasses.replace(robot, tau_max_source=sources)
    return HumanArm(robot, muscles, factors, MODELLING, prov)
