"""``geosyn schema [SECTION]`` (every config field: type, default, unit, meaning) and
``geosyn init NAME`` (a commented experiment template), listed in ``COMMANDS`` for
`geosyn.experiments.cli`. The schema and the robot are imported only when they run."""

from __future__ import annotations

import argparse
import difflib
import re
from pathlib import Path
from typing import Any

import numpy as np

from geosyn.experiments.cli.registry import Command
from geosyn.experiments.errors import ConfigError


def _sections() -> dict[str, list[Any]]:
    """SECTION name -> the field docs it shows: every top-level section, every item
    ``type`` (``qp``, ``push``, ``box``, ...), ``params`` and each kind's name."""
    from geosyn.experiments.procedures import PROCEDURES
    from geosyn.experiments.schema import ExperimentConfig
    from geosyn.experiments.schema.describe import walk

    docs = list(walk(ExperimentConfig))
    out: dict[str, list[Any]] = {"all": docs}
    for d in docs:
        top = d.path.split(".")[0].split("[")[0]
        out.setdefault(top, []).append(d)
        for part in d.path.split(".")[:-1]:
            if "[type=" in part:
                out.setdefault(part.split("[type=")[1].rstrip("]"), []).append(d)
    params = out.setdefault("params", out.get("params", []))
    for kind, proc in sorted(PROCEDURES.items()):
        kind_docs = list(walk(proc.Params, f"params[kind={kind}]."))
        params += kind_docs
        out[kind] = kind_docs
    return out


def kinds_table() -> str:
    """Markdown table: which config sections each registered kind reads."""
    from geosyn.experiments.procedures import PROCEDURES
    from geosyn.experiments.procedures.base import SECTIONS

    lines = [
        "| kind | " + " | ".join(SECTIONS) + " |",
        "|---|" + "---|" * len(SECTIONS),
    ]
    for kind, proc in sorted(PROCEDURES.items()):
        if proc.sections is None:
            cells = ["?"] * len(SECTIONS)
        else:
            cells = ["yes" if s in proc.sections else "" for s in SECTIONS]
        lines.append(f"| {kind} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def format_docs(docs: list[Any]) -> str:
    """The field docs as text: ``path: type = default [unit]`` then the meaning."""
    lines = []
    for d in docs:
        unit = f" [{d.unit}]" if d.unit else ""
        lines.append(f"{d.path}: {d.type} = {d.default}{unit}")
        if d.meaning:
            lines.append(f"    {d.meaning}")
    return "\n".join(lines)


def schema_text(section: str | None = None) -> str:
    """The text ``geosyn schema SECTION`` prints (None: the top-level sections).

    Raises:
        ConfigError: unknown section (the closest names are suggested).
    """
    sections = _sections()
    if section is None:
        top = [d for d in sections["all"] if "." not in d.path]
        head = (
            "Sections of an experiment file (geosyn schema SECTION for its fields;"
            " SECTION may also be an item type such as qp or push, a kind such as tracking,"
            " 'kinds' (the sections each kind reads) or 'all'):"
        )
        return head + "\n\n" + format_docs(top)
    if section == "kinds":
        return (
            "Sections each kind reads ('?': not declared; a run logs a set section its kind"
            " does not read):\n\n" + kinds_table()
        )
    if section not in sections:
        valid = [*sections, "kinds"]
        raise ConfigError("schema", section, unknown_name_message(section, valid))
    return format_docs(sections[section])


def unknown_name_message(name: str, valid: list[str], what: str = "section") -> str:
    """``unknown <what> 'x'; did you mean 'y'? valid: ...`` (closest by difflib)."""
    close = difflib.get_close_matches(name, valid, n=3, cutoff=0.6)
    hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
    return f"unknown {what} {name!r}{hint} valid: {', '.join(sorted(valid))}"


def _schema_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "section",
        nargs="?",
        metavar="SECTION",
        help="a section (controllers, simulation, ...), an item type (qp, push, box, ...),"
        " a kind (tracking, ...), params, or all",
    )


def cmd_schema(args: argparse.Namespace) -> int:
    print(schema_text(args.section))
    return 0


def _start_and_goal(robot: Any) -> tuple[list[float], list[float]]:
    """A start at the model's zero configuration moved 0.1 rad inside finite position
    limits, and a goal 0.4 rad away on the first three joints (kept inside too); on a
    robot with coupled joints both are moved onto the coupling (its independent joints
    kept)."""
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    finite = (np.abs(lo) < 1e3) & (np.abs(hi) < 1e3) & (hi - lo > 0.3)
    start = np.where(finite, np.clip(0.0, lo + 0.1, hi - 0.1), 0.0)
    goal = start.copy()
    goal[: min(3, robot.nq)] += 0.4
    goal = np.where(finite, np.clip(goal, lo + 0.05, hi - 0.05), goal)
    coupling = getattr(robot, "coupling", None)
    if coupling is not None:
        start, goal = coupling.q(coupling.z(start)), coupling.q(coupling.z(goal))
    return [round(float(x), 3) for x in start], [round(float(x), 3) for x in goal]


def template(name: str, robot_name: str) -> str:
    """A commented ``kind: tracking`` experiment on ``robot_name`` that validates as is.

    Raises:
        GeosynError: the robot cannot be loaded.
    """
    from geosyn.robots import load_robot

    robot = load_robot(robot_name)
    start, goal = _start_and_goal(robot)
    return f"""\
# {name}: a closed-loop experiment (kind: tracking). Run it with
#   geosyn run {name}.yaml
# Every field, its unit and default: geosyn schema (or geosyn schema SECTION).
name: {name}
description: >-
  {robot.name} tracks the geodesic between two configurations with two controllers.
kind: tracking            # the general closed loop; `geosyn list` shows the others
seed: 0
robot:
  name: {robot_name}      # a built-in robot (geosyn robots) or a .urdf/.xml/.mjcf path
metric:
  terms: []               # shaping terms: {{type: obstacle}}, {{type: load, payload: 0}},
                          # {{type: joint_limit}} (geosyn schema terms)
scene:
  payloads: []            # e.g. - {{mass: 0.5, radius: 0.03, name: object}}
  obstacles: []           # e.g. - {{type: box, center: [0.4, 0.0, 0.2], half_extents: [0.05, 0.05, 0.05]}}
reference:                # what the controllers track (geosyn schema reference)
  type: log               # log: the geodesic to a goal; goals: through several;
                          # planned: around the obstacles; combination: of synergies
  q_start: {start}   # [rad]
  goal: {goal}   # [rad]
  duration: 2.0           # [s] geodesic time
  time_scale: 1.0         # > 1 is slower
  rest_to_rest: true      # start and end at rest (false: constant speed, steps to rest)
controllers:              # each one runs the experiment (geosyn schema controllers)
  - type: computed_torque
    kp: 400.0             # [1/s^2]
    kd: 40.0              # [1/s]
  - type: qp              # limit-aware inverse dynamics
    kp: 400.0
    kd: 40.0
disturbances: []          # e.g. - {{type: push, body: {robot.ee_frame}, force: [10.0, 0.0, 0.0], start: 0.5, duration: 0.05}}
                          # also wrench, payload_change, torque_noise, sensor_noise, latency
simulation:
  duration: 2.5           # [s]
  control_dt: 0.001       # [s]
outputs:
  plots: true
  csv: true               # data/<controller>.csv with named columns
  video: false
params:
  threshold: 0.01         # [rad] error below which a run has recovered after a disturbance
"""


def _init_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("name", metavar="NAME", help="experiment name (the file is NAME.yaml)")
    p.add_argument(
        "--robot",
        default="planar2",
        help="a built-in robot or a .urdf/.xml/.mjcf file path (default planar2)",
    )
    p.add_argument("--out", metavar="FILE", help="where to write (default NAME.yaml)")
    p.add_argument("--force", action="store_true", help="replace an existing file")


def cmd_init(args: argparse.Namespace) -> int:
    if not re.fullmatch(r"[A-Za-z0-9_\-.]+", args.name):
        raise ConfigError("init", "name", "use letters, digits, '_', '-' and '.' only")
    path = Path(args.out or f"{args.name}.yaml")
    if path.exists() and not args.force:
        raise ConfigError(str(path), None, "exists; choose another --out or pass --force")
    from geosyn.core import GeosynError
    from geosyn.robots import BUILTINS

    robot = args.robot
    if robot not in BUILTINS:
        if not robot.lower().endswith((".urdf", ".xml", ".mjcf")):
            reason = unknown_name_message(robot, list(BUILTINS), "robot")
            raise ConfigError("init", "--robot", reason + " (or a .urdf/.xml/.mjcf path)")
        if not Path(robot).is_file():
            raise ConfigError("init", "--robot", f"robot file {robot!r} does not exist")
        robot = str(Path(robot).resolve())  # the config then runs from any directory
    try:
        text = template(args.name, robot)
    except GeosynError as err:
        raise ConfigError("init", "--robot", str(err)) from err
    path.write_text(text, encoding="utf-8")
    print(f"wrote {path}; run it with: geosyn run {path}")
    return 0


COMMANDS = (
    Command(
        "schema",
        cmd_schema,
        "every config field with its type, default, unit and meaning",
        _schema_arguments,
    ),
    Command(
        "init",
        cmd_init,
        "write a commented experiment template NAME.yaml",
        _init_arguments,
    ),
)

__all__ = [
    "COMMANDS",
    "format_docs",
    "kinds_table",
    "schema_text",
    "template",
    "unknown_name_message",
]
