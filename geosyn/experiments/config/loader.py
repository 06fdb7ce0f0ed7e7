"""Loading experiment configs: YAML files or built-in names, ``--set`` overrides, validation.

Problems are reported as one `ConfigError` naming the file and the field path, e.g.
``panda_push_recovery.yaml: controllers.1.kp: Input should be greater than or equal to 0``,
with every other problem of the same stage listed after the first
(`geosyn.experiments.config.problems`; unknown keys and types name the closest valid ones).
Validation order: YAML syntax, overrides, then one stage: ``robot`` (the robot is loaded
to learn its DoF), the whole document with the DoF as context, ``kind`` against the
registered procedures, ``params`` against the procedure's ``Params`` model; then
resource limits, cross-field checks and names only the built scene knows.

``--set key.path=value`` sets a field; ``--set key.path+=value`` appends to a list.
"""

from __future__ import annotations

import copy
import difflib
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ValidationError

from geosyn.core.errors import GeosynError
from geosyn.experiments.config.chatter import captured_stderr
from geosyn.experiments.config.problems import raise_problems, validation_errors
from geosyn.experiments.config.resource_limits import (
    SAFE_LOADER,
    DuplicateKey,
    check_nesting,
    check_structure,
    nesting_error,
    read_text,
    resource_errors,
)
from geosyn.experiments.config.start_clearance import start_inside_errors
from geosyn.experiments.errors import ConfigError
from geosyn.experiments.procedures import PROCEDURES
from geosyn.experiments.procedures.base import ignored_sections
from geosyn.experiments.run.scene import build_payloads, mjcf_obstacles
from geosyn.experiments.schema import ExperimentConfig, RobotConfig, consistency_errors
from geosyn.robots import load_robot
from geosyn.sim import build_scene

#: Folder of the built-in experiment configs.
CONFIG_DIR = Path(__file__).resolve().parents[1] / "configs"


def builtin_names() -> list[str]:
    """Names of the built-in experiments (``experiments/configs/*.yaml``), sorted."""
    return sorted(p.stem for p in CONFIG_DIR.glob("*.yaml"))


def resolve_source(source: str | Path) -> Path:
    """The YAML file of a built-in experiment name or of a path.

    Raises:
        ConfigError: neither a built-in name nor an existing file.
    """
    text = str(source)
    if text in builtin_names():
        return CONFIG_DIR / f"{text}.yaml"
    path = Path(text)
    if path.is_file():
        return path
    if path.suffix.lower() in (".yaml", ".yml") or path.parent != Path("."):
        raise ConfigError(text, None, "no such file")
    raise ConfigError(
        text, None, f"not a built-in experiment or a file; built-ins: {', '.join(builtin_names())}"
    )


def read_yaml(path: Path) -> dict[str, Any]:
    """Parse a YAML mapping (safe loader: plain data only).

    Raises:
        ConfigError: unreadable file, bad syntax or not a mapping.
    """
    text = read_text(path)
    try:
        data = yaml.load(text, Loader=SAFE_LOADER)
    except RecursionError:  # PyYAML's pure-Python parser, nested below geosyn's token count
        raise nesting_error(path.name) from None
    except (ValueError, TypeError, OverflowError) as err:  # e.g. a date 2001-13-01
        raise ConfigError(path.name, None, f"invalid YAML value: {err}") from None
    except yaml.YAMLError as err:
        check_nesting(text, path.name)  # the parser may have met a depth limit of its own
        mark = getattr(err, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
        problem = getattr(err, "problem", None) or str(err)
        raise ConfigError(
            path.name, None, f"invalid YAML: {where}{problem}".replace("\n", " ")
        ) from err
    if not isinstance(data, dict):
        raise ConfigError(
            path.name, None, f"must be a YAML mapping of sections, got {type(data).__name__}"
        )
    check_structure(data, path.name)
    return data


def parse_override(text: str) -> tuple[str, Any]:
    """Split ``key.path=value`` (or ``key.path+=value``, which appends: the key keeps its
    ``+``); the value is parsed as YAML (``0.5``, ``[1, 2]``, ``true``, ``{type: qp}``).

    Raises:
        ConfigError: no ``=`` or an empty key.
    """
    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or not key or any(not part for part in key.split(".")):
        raise ConfigError("--set", text, "expected key.path=value (e.g. simulation.duration=1.0)")
    try:
        parsed = yaml.load(value, Loader=SAFE_LOADER) if value.strip() else ""
    except RecursionError:
        raise nesting_error("--set", key) from None
    except (ValueError, TypeError, OverflowError) as err:
        raise ConfigError("--set", key, f"invalid YAML value: {err}") from None
    except DuplicateKey as err:  # YAML, but a wrong one: not a plain string either
        raise ConfigError("--set", key, f"invalid YAML value: {err.problem}") from None
    except yaml.YAMLError:
        check_nesting(value, "--set", key)
        parsed = value
    check_structure(parsed, f"--set {key}")
    return key, parsed


def apply_override(data: dict[str, Any], key: str, value: Any) -> None:
    """Set ``data[key.path] = value`` in place; missing mapping levels are created.

    A key ending in ``+`` appends to the list there instead (``--set
    controllers+={type: qp}`` adds a controller; a missing list is created).

    Raises:
        ConfigError: the path goes through a scalar, a list index is not an index in
            range, or ``+`` names something that is not a list.
    """
    if key.endswith("+"):
        path = key[:-1]
        current = _get(data, path)
        if current is not None and not isinstance(current, list):
            raise ConfigError("--set", key, f"{path} is not a list; '+=' appends to a list")
        apply_override(data, path, [*(current or []), value])
        return
    parts = key.split(".")
    node: Any = data
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        here = ".".join(parts[:depth]) or "<top level>"
        if isinstance(node, dict):
            if last:
                node[part] = value
            else:
                if node.get(part) is None:
                    node[part] = {}
                node = node[part]
        elif isinstance(node, list):
            if not part.lstrip("-").isdigit():
                raise ConfigError("--set", key, f"{here} is a list; {part!r} is not an index")
            i = int(part)
            if not 0 <= i < len(node):
                raise ConfigError(
                    "--set", key, f"index {i} out of range: {here} has {len(node)} item(s)"
                )
            if last:
                node[i] = value
            else:
                node = node[i]
        else:
            raise ConfigError("--set", key, f"{here} is a value ({node!r}), not a section")


def _get(data: Any, path: str) -> Any:
    """The value at a dotted path (None when any level is missing)."""
    node = data
    for part in path.split("."):
        if isinstance(node, dict):
            node = node.get(part)
        elif (
            isinstance(node, list)
            and part.lstrip("-").isdigit()
            and -len(node) <= int(part) < len(node)
        ):
            node = node[int(part)]
        else:
            return None
    return node


def scene_errors(cfg: ExperimentConfig, robot: Any) -> list[tuple[str, str]]:
    """Names that only the built scene can check: the MuJoCo scene file, payload frames,
    pushed bodies, load frames.

    Builds the MuJoCo scene once (only when a push or wrench names a body).
    """
    if cfg.scene.mjcf is not None:  # the file loads and gives obstacles
        try:
            file = mjcf_obstacles(cfg)
        except GeosynError as err:
            return [("scene.mjcf.file", f"{cfg.scene.mjcf.file}: {err}")]
        if file is not None and not file.shapes:
            left = "; ".join(file.skipped) or "it has no geoms"
            return [("scene.mjcf.file", f"{cfg.scene.mjcf.file}: no static geom to use ({left})")]
    frames = [f.name for f in robot.model.frames]
    for i, p in enumerate(cfg.scene.payloads):
        if (
            p.frame is not None
            and p.frame not in frames
            and not robot.model.existJointName(p.frame)
        ):
            return [
                (
                    f"scene.payloads.{i}.frame",
                    f"{p.frame!r} is not a frame of {robot.name!r}; available: {', '.join(frames)}",
                )
            ]
    for i, t in enumerate(cfg.metric.terms):
        if t.type == "load" and t.frame is not None and t.frame not in frames:
            return [
                (
                    f"metric.terms.{i}.frame",
                    f"{t.frame!r} is not a frame of {robot.name!r}; available: {', '.join(frames)}",
                )
            ]
    bodies = [(i, d.body) for i, d in enumerate(cfg.disturbances) if d.type in ("push", "wrench")]
    names = [p.name for p in cfg.scene.payloads if p.name]
    for i, d in enumerate(cfg.disturbances):
        if d.type == "payload_change" and isinstance(d.payload, str) and d.payload not in names:
            return [
                (
                    f"disturbances.{i}.payload",
                    f"no payload named {d.payload!r}; named payloads: {', '.join(names) or 'none'}",
                )
            ]
    if bodies and not robot.floating:  # a floating robot's pushes: run.floating checks them
        try:
            scene = build_scene(robot, payloads=build_payloads(cfg, robot))
        except GeosynError as err:
            return [("scene", str(err))]
        for i, body in bodies:
            try:
                scene.resolve_body(body)
            except GeosynError:
                return [
                    (
                        f"disturbances.{i}.body",
                        f"{body!r} is not a body, link or frame of {robot.name!r}; available bodies: {', '.join(scene.body_names())}",
                    )
                ]
    return []


def unused_errors(cfg: ExperimentConfig) -> list[tuple[str, str]]:
    """Sections the config sets that its kind does not read (they would have no effect)."""
    proc = PROCEDURES[cfg.kind]
    return [
        (
            section,
            f"kind {cfg.kind!r} does not read this section (it reads:"
            f" {', '.join(proc.sections or ())}); remove it, or pass --allow-unused"
            " to run anyway (the run log names it)",
        )
        for section in ignored_sections(cfg, proc)
    ]


def validate_config(
    data: Mapping[str, Any], file: str = "<config>", allow_unused: bool = False
) -> ExperimentConfig:
    """Validate a config document (see the module doc for the order of checks).

    Args:
        data: the parsed YAML mapping (not modified).
        file: name used in error messages.
        allow_unused: accept sections that the kind does not read (set away from their
            defaults; they have no effect, and a run logs them); refused by default.

    Returns:
        The config; ``params`` holds the procedure's validated parameters with defaults.

    Raises:
        ConfigError: naming ``file`` and the field path of the first problem, with every
            other problem of the same stage listed after it (the structure, robot, kind
            and params are one stage; resource limits, cross-field and procedure checks
            and scene names come after it).
    """
    check_structure(dict(data), file)
    data = copy.deepcopy(dict(data))
    problems: dict[str, str] = {}  # every problem of the file, one per field
    robot = None
    if "robot" not in data:
        problems["robot"] = "Field required"
    else:
        try:
            robot_cfg = RobotConfig.model_validate(data["robot"])
            with captured_stderr() as parser_output:  # the URDF parser prints its errors
                try:
                    robot = load_robot(
                        robot_cfg.name, **robot_cfg.options.model_dump(exclude_none=True)
                    )
                except GeosynError as err:
                    problems["robot"] = str(err)
        except ValidationError as err:
            problems.update(validation_errors(err, data["robot"], RobotConfig, "robot"))
        else:
            if "robot" in problems:  # the parser's own words, in geosyn's one line
                problems["robot"] += parser_output.said()
            elif parser_output.text:  # a success's chatter stays on stderr, as printed
                sys.stderr.write(parser_output.text)
    context = {"nv": robot.nv} if robot is not None else None
    cfg = None
    try:
        cfg = ExperimentConfig.model_validate(data, context=context)
    except ValidationError as err:
        for field, reason in validation_errors(err, data, ExperimentConfig):
            if not any(field == f or field.startswith(f + ".") for f in problems):
                problems[field] = reason
    kind = data.get("kind")
    params: Any = None
    if isinstance(kind, str) and kind not in PROCEDURES:
        close = difflib.get_close_matches(kind, list(PROCEDURES), n=1, cutoff=0.6)
        hint = f"; did you mean {close[0]!r}?" if close else ";"
        problems["kind"] = (
            f"unknown kind {kind!r}{hint} registered: {', '.join(sorted(PROCEDURES))}"
        )
    elif isinstance(kind, str) and isinstance(data.get("params", {}), dict):
        params_model: type[BaseModel] = PROCEDURES[kind].Params
        raw = data.get("params") or {}
        try:
            params = params_model.model_validate(raw, context=context)
        except ValidationError as err:
            problems.update(validation_errors(err, raw, params_model, "params"))
    if problems or cfg is None or robot is None or params is None:
        raise_problems(file, list(problems.items()) or [("<top level>", "invalid config")])
    cfg.params = params.model_dump(mode="json")
    later = resource_errors(cfg)
    later += consistency_errors(cfg, robot.nv) if not later else []
    later += PROCEDURES[cfg.kind].check(cfg, params, robot) if not later else []
    later += scene_errors(cfg, robot) if not later else []
    later += start_inside_errors(cfg, robot) if not later else []
    later += unused_errors(cfg) if not later and not allow_unused else []
    if later:
        raise_problems(file, later)
    return cfg


def load_config(
    source: str | Path, overrides: Iterable[str] = (), allow_unused: bool = False
) -> tuple[ExperimentConfig, Path]:
    """Read, override and validate an experiment.

    Args:
        source: a built-in experiment name or a YAML path.
        overrides: ``key.path=value`` strings applied in order before validation.
        allow_unused: accept sections the kind does not read (see `validate_config`).

    Returns:
        (the validated config, the YAML file it came from).

    Raises:
        ConfigError: anything wrong, naming the file and the field path.
    """
    path = resolve_source(source)
    data = read_yaml(path)
    robot = data.get("robot")
    if isinstance(robot, dict) and isinstance(robot.get("name"), str):
        if Path(robot["name"]).suffix.lower() in (".urdf", ".xml", ".mjcf"):  # not a built-in
            robot["name"] = _beside(path, robot["name"])
    for text in overrides:
        key, value = parse_override(text)
        apply_override(data, key, value)
    scene = data.get("scene")
    mjcf = scene.get("mjcf") if isinstance(scene, dict) else None
    if isinstance(mjcf, dict) and isinstance(mjcf.get("file"), str):
        mjcf["file"] = _beside(path, mjcf["file"])
    return validate_config(data, path.name, allow_unused), path


def _beside(config: Path, name: str) -> str:
    """A file path of a config: relative to the config file (made absolute) when such a
    file exists there, else as written."""
    file = Path(name)
    if not file.is_absolute() and (config.parent / file).is_file():
        return str((config.parent / file).resolve())
    return name


def dump_config(cfg: ExperimentConfig) -> str:
    """The resolved config as YAML (loads back to an equal config)."""
    return yaml.safe_dump(cfg.model_dump(mode="json"), sort_keys=False, allow_unicode=True)


__all__ = [
    "CONFIG_DIR",
    "apply_override",
    "builtin_names",
    "dump_config",
    "load_config",
    "parse_override",
    "read_yaml",
    "resolve_source",
    "unused_errors",
    "validate_config",
]
