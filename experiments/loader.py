"""Loading experiment configs: YAML files or built-in names, ``--set`` overrides, validation.

Every problem is reported as a `ConfigError` naming the file and the field path, e.g.
``panda_push_recovery.yaml: controllers.1.kp: Input should be greater than or equal to 0``.
Validation order: YAML syntax, overrides, ``robot`` (the robot is loaded to learn its
DoF), the whole document with the DoF as context, ``kind`` against the registered
procedures, ``params`` against the procedure's ``Params`` model, cross-field checks.
"""

from __future__ import annotations

import copy
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ValidationError

from geosyn.core.errors import GeosynError
from geosyn.experiments.errors import ConfigError
from geosyn.experiments.schema import ExperimentConfig, RobotConfig, consistency_errors

#: Folder of the built-in experiment configs.
CONFIG_DIR = Path(__file__).resolve().parent / "configs"


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
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise ConfigError(path.name, None, f"cannot read: {err.strerror or err}") from err
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
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
    return data


def parse_override(text: str) -> tuple[str, Any]:
    """Split ``key.path=value``; the value is parsed as YAML (``0.5``, ``[1, 2]``, ``true``).

    Raises:
        ConfigError: no ``=`` or an empty key.
    """
    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or not key or any(not part for part in key.split(".")):
        raise ConfigError("--set", text, "expected key.path=value (e.g. simulation.duration=1.0)")
    try:
        parsed = yaml.safe_load(value) if value.strip() else ""
    except yaml.YAMLError:
        parsed = value
    return key, parsed


def apply_override(data: dict[str, Any], key: str, value: Any) -> None:
    """Set ``data[key.path] = value`` in place; missing mapping levels are created.

    Raises:
        ConfigError: the path goes through a scalar, or a list index is not an index in
            range.
    """
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


def _field_path(loc: tuple[Any, ...], data: Any) -> str:
    """Dotted field path of a pydantic error location, without union/tag members."""
    out: list[str] = []
    node = data
    for item in loc:
        if isinstance(node, dict):
            if item in node:
                out.append(str(item))
                node = node[item]
            elif isinstance(item, str) and node.get("type") == item:
                continue  # discriminated-union tag
            elif isinstance(item, str) and ("[" in item or item.startswith("function-")):
                continue  # union member or validator name
            else:
                out.append(str(item))
                node = None
        elif isinstance(node, list) and isinstance(item, int):
            out.append(str(item))
            node = node[item] if 0 <= item < len(node) else None
        elif node is None:
            if not (isinstance(item, str) and ("[" in item or item.startswith("function-"))):
                out.append(str(item))
        else:
            break  # a scalar: the remaining items name union members
    return ".".join(out) or "<top level>"


def _raise_validation(err: ValidationError, file: str, data: Any, prefix: str = "") -> None:
    first = err.errors()[0]
    field = _field_path(tuple(first["loc"]), data)
    if prefix:
        field = prefix if field == "<top level>" else f"{prefix}.{field}"
    msg = first["msg"]
    if first["type"] == "extra_forbidden":
        msg = "unknown key (Extra inputs are not permitted)"
    elif first["type"] == "union_tag_invalid":
        ctx = first.get("ctx", {})
        msg = f"unknown type {ctx.get('tag')!r}; allowed: {ctx.get('expected_tags')}"
    elif first["type"] == "union_tag_not_found":
        msg = f"missing 'type'; allowed: {first.get('ctx', {}).get('expected_tags', '')}"
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, ") :]
    paths = {_field_path(tuple(e["loc"]), data) for e in err.errors()}
    more = len(paths) - 1
    if more:
        msg += f" (and errors in {more} more field{'s' if more > 1 else ''})"
    raise ConfigError(file, field, msg) from None


def scene_errors(cfg: ExperimentConfig, robot: Any) -> list[tuple[str, str]]:
    """Names that only the built scene can check: payload frames, pushed bodies, load frames.

    Builds the MuJoCo scene once (only when a push or wrench names a body).
    """
    from geosyn.experiments.build import build_payloads
    from geosyn.sim import build_scene

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
    if bodies:
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


def validate_config(data: Mapping[str, Any], file: str = "<config>") -> ExperimentConfig:
    """Validate a config document (see the module doc for the order of checks).

    Args:
        data: the parsed YAML mapping (not modified).
        file: name used in error messages.

    Returns:
        The config; ``params`` holds the procedure's validated parameters with defaults.

    Raises:
        ConfigError: the first problem found, naming ``file`` and the field path.
    """
    from geosyn.experiments.procedures import PROCEDURES
    from geosyn.robots import load_robot

    data = copy.deepcopy(dict(data))
    if "robot" not in data:
        raise ConfigError(file, "robot", "Field required")
    try:
        robot_cfg = RobotConfig.model_validate(data["robot"])
    except ValidationError as err:
        _raise_validation(err, file, data["robot"], "robot")
    try:
        robot = load_robot(robot_cfg.name, **robot_cfg.options.model_dump(exclude_none=True))
    except GeosynError as err:
        raise ConfigError(file, "robot", str(err)) from None
    try:
        cfg = ExperimentConfig.model_validate(data, context={"nv": robot.nv})
    except ValidationError as err:
        _raise_validation(err, file, data)
    if cfg.kind not in PROCEDURES:
        raise ConfigError(
            file, "kind", f"unknown kind {cfg.kind!r}; registered: {', '.join(sorted(PROCEDURES))}"
        )
    params_model: type[BaseModel] = PROCEDURES[cfg.kind].Params
    try:
        params = params_model.model_validate(cfg.params, context={"nv": robot.nv})
    except ValidationError as err:
        _raise_validation(err, file, cfg.params, "params")
    cfg.params = params.model_dump(mode="json")
    problems = consistency_errors(cfg, robot.nv) + PROCEDURES[cfg.kind].check(cfg, params, robot)
    problems += scene_errors(cfg, robot) if not problems else []
    if problems:
        field, reason = problems[0]
        raise ConfigError(file, field, reason)
    return cfg


def load_config(source: str | Path, overrides: Iterable[str] = ()) -> tuple[ExperimentConfig, Path]:
    """Read, override and validate an experiment.

    Args:
        source: a built-in experiment name or a YAML path.
        overrides: ``key.path=value`` strings applied in order before validation.

    Returns:
        (the validated config, the YAML file it came from).

    Raises:
        ConfigError: anything wrong, naming the file and the field path.
    """
    path = resolve_source(source)
    data = read_yaml(path)
    robot = data.get("robot")
    if isinstance(robot, dict) and isinstance(robot.get("name"), str):
        # a robot file path is relative to the config file (then made absolute)
        name = Path(robot["name"])
        if name.suffix.lower() in (".urdf", ".xml", ".mjcf") and not name.is_absolute():
            if (path.parent / name).is_file():
                robot["name"] = str((path.parent / name).resolve())
    for text in overrides:
        key, value = parse_override(text)
        apply_override(data, key, value)
    return validate_config(data, path.name), path


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
    "validate_config",
]
