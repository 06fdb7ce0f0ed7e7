"""Joint torque limits and actuators as a robot file states them.

A limit comes from the file (MJCF ``<motor ctrlrange>`` x ``gear``, an actuator's
``forcerange`` x ``gear``, a joint's ``actuatorfrcrange``; URDF ``<limit effort>``), from
an explicit user override, or, only where the file gives none, from a documented default;
`Robot.tau_max_source` says which, joint by joint, and loading warns about every default.

geosyn always commands joint torques: in simulation they are applied as generalized forces
(MuJoCo ``qfrc_applied``), whatever actuators the file declares. A position or velocity
servo of the file is described (`ActuatorInfo`), never driven by geosyn.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.robots.errors import RobotWarning

if TYPE_CHECKING:
    import mujoco

DEFAULT_TAU_MAX = 100.0
"""Torque limit [N m or N] used for a joint whose file states none (reported)."""

GEOSYN_COMMANDS = "joint torque (qfrc_applied); this actuator is not driven by geosyn"
"""What geosyn commands, whatever the file's actuator is."""


@dataclass(frozen=True)
class ActuatorInfo:
    """An actuator declared by a robot file, as geosyn understands it.

    Attributes:
        name: actuator name in the file.
        joint: name of the joint it drives ('' for tendon or site transmissions).
        kind: ``motor``, ``position servo``, ``velocity servo``, ``general`` or
            ``tendon/site transmission``.
        gear: transmission gear (joint torque per unit actuator force).
        ctrlrange: (lo, hi) control range, or None when unlimited.
        forcerange: (lo, hi) actuator force range, or None when unlimited.
        geosyn_commands: what geosyn commands instead (always joint torques).
    """

    name: str
    joint: str
    kind: str
    gear: float
    ctrlrange: tuple[float, float] | None
    forcerange: tuple[float, float] | None
    geosyn_commands: str = GEOSYN_COMMANDS


def _symmetric(lo: float, hi: float) -> float:
    """The symmetric bound of a range: the smaller magnitude, else the larger one."""
    small = min(abs(lo), abs(hi))
    return small if small > 0 else max(abs(lo), abs(hi))


def _kind(m: mujoco.MjModel, a: int) -> str:
    gain, bias = m.actuator_gainprm[a], m.actuator_biasprm[a]
    if m.actuator_gaintype[a] != 0:
        return "general"
    if m.actuator_biastype[a] == 0:
        return "motor"
    if m.actuator_biastype[a] == 1:
        if bias[1] == -gain[0] and bias[0] == 0:
            return "position servo"
        if bias[1] == 0 and bias[2] == -gain[0] and bias[0] == 0:
            return "velocity servo"
    return "general"


def mjcf_actuation(
    m: mujoco.MjModel, joint_names: Sequence[str]
) -> tuple[dict[str, tuple[float, str]], tuple[ActuatorInfo, ...]]:
    """Torque limits and actuators of a compiled MuJoCo model.

    Args:
        m: compiled model.
        joint_names: (njnt,) joint names (geosyn's, with unnamed joints named).

    Returns:
        ``{joint: (tau_max, source)}`` for the joints whose file states a limit, and the
        actuators.
    """
    import mujoco

    limits: dict[str, tuple[float, str]] = {}
    infos: list[ActuatorInfo] = []
    for a in range(m.nu):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a) or f"actuator{a}"
        ctrl = (
            tuple(float(x) for x in m.actuator_ctrlrange[a]) if m.actuator_ctrllimited[a] else None
        )
        force = (
            tuple(float(x) for x in m.actuator_forcerange[a])
            if m.actuator_forcelimited[a]
            else None
        )
        gear = float(m.actuator_gear[a, 0])
        if m.actuator_trntype[a] not in (0, 1):  # joint, joint in parent
            infos.append(ActuatorInfo(name, "", "tendon/site transmission", gear, ctrl, force))  # type: ignore[arg-type]
            continue
        joint = joint_names[int(m.actuator_trnid[a, 0])]
        kind = _kind(m, a)
        infos.append(ActuatorInfo(name, joint, kind, gear, ctrl, force))  # type: ignore[arg-type]
        bounds: list[tuple[float, str]] = []
        if force is not None:
            bounds.append((abs(gear) * _symmetric(*force), f"forcerange x gear of {kind} {name!r}"))
        if kind == "motor" and ctrl is not None:
            gain = abs(float(m.actuator_gainprm[a, 0]))
            bounds.append(
                (abs(gear) * gain * _symmetric(*ctrl), f"ctrlrange x gear of motor {name!r}")
            )
        if bounds:
            tau, src = min(bounds)
            if joint in limits:  # several actuators on one joint add up
                prev, prev_src = limits[joint]
                tau, src = prev + tau, f"{prev_src} + {src}"
            limits[joint] = (tau, "file: " + src)
    for j in range(m.njnt):
        if m.jnt_actfrclimited[j]:
            tau = _symmetric(*(float(x) for x in m.jnt_actfrcrange[j]))
            name = joint_names[j]
            if name not in limits or tau < limits[name][0]:
                limits[name] = (tau, f"file: actuatorfrcrange of joint {name!r}")
    return limits, tuple(infos)


def resolve_tau_max(
    joint_names: Sequence[str],
    from_file: Mapping[str, tuple[float, str]],
    override: float | Sequence[float] | Mapping[str, float] | None,
    default: float,
    robot_name: str,
) -> tuple[np.ndarray, tuple[str, ...]]:
    """Per-joint torque limits and where each came from; warns about defaults.

    Args:
        joint_names: (nv,) joint names.
        from_file: ``{joint: (tau_max, source)}`` stated by the file (> 0, finite).
        override: user limits: a scalar, (nv,) values, or ``{joint: value}`` [N m or N].
        default: limit for a joint with neither [N m or N].
        robot_name: for the warning.

    Returns:
        (nv,) limits and (nv,) sources (``file: ...``, ``user``, ``default ...``).

    Raises:
        InvalidArgument: an override that is not > 0, of the wrong size, or naming an
            unknown joint.
    """
    n = len(joint_names)
    user: dict[str, float] = {}
    if isinstance(override, Mapping):
        unknown = [k for k in override if k not in joint_names]
        if unknown:
            raise InvalidArgument(
                f"tau_max names unknown joints {unknown}; available: {', '.join(joint_names)}"
            )
        user = {k: float(v) for k, v in override.items()}
    elif override is not None:
        arr = (
            np.broadcast_to(np.asarray(override, dtype=np.float64), (n,))
            if np.ndim(override) == 0
            else np.asarray(override, dtype=np.float64)
        )
        if arr.shape != (n,):
            raise InvalidArgument(f"tau_max must be a scalar or ({n},), got shape {arr.shape}")
        user = dict(zip(joint_names, (float(x) for x in arr), strict=True))
    bad = {k: v for k, v in user.items() if not (np.isfinite(v) and v > 0)}
    if bad:
        raise InvalidArgument(f"tau_max must be finite and > 0, got {bad}")
    tau = np.empty(n)
    sources: list[str] = []
    defaulted: list[str] = []
    for i, name in enumerate(joint_names):
        if name in user:
            tau[i], src = user[name], "user"
        elif name in from_file:
            tau[i], src = from_file[name]
        else:
            tau[i], src = default, f"default {default:g} (the file states no limit)"
            defaulted.append(name)
        sources.append(src)
    if defaulted:
        warnings.warn(
            f"robot {robot_name!r}: no torque limit in the file for joints {defaulted};"
            f" using the default {default:g} (set tau_max=... to override)",
            RobotWarning,
            stacklevel=4,
        )
    return tau, tuple(sources)
