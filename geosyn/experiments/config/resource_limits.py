"""The input boundary of experiment configs: how a file is read, how big and deep it may
be, and what resources a config may ask for.

A config file is read as UTF-8 (a UTF-8/16/32 byte-order mark is honoured) and refused if
binary, larger than `MAX_CONFIG_BYTES`, nested deeper than `MAX_DEPTH` or holding more
than `MAX_VALUES` values (aliases expanded). A validated config is refused if a duration
needs more than ``limit("ticks")`` control ticks or a latency outlasts the run
(`resource_errors`): resource bombs fail up front with the limit and how to raise it
(``GEOSYN_MAX_<NAME>``), instead of allocating gigabytes.
"""

from __future__ import annotations

import codecs
import math
import os
import re
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import yaml

from geosyn.experiments.errors import ConfigError
from geosyn.experiments.schema import ExperimentConfig

#: Largest config file [bytes] (a config is a few kB; parsing is bounded by this).
MAX_CONFIG_BYTES = 256 << 10
_BASE_LOADER: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_MERGE_TAG = "tag:yaml.org,2002:merge"


class DuplicateKey(yaml.constructor.ConstructorError):
    """A YAML mapping repeats a key."""


class UniqueKeyLoader(_BASE_LOADER):
    """libyaml's safe loader when PyYAML has it (8x faster on big files), else PyYAML's
    own, refusing a mapping that repeats a key (YAML says keys are unique; PyYAML keeps
    the last silently). Keys brought in by a ``<<`` merge may be overridden, as YAML says.
    """

    def construct_mapping(self, node: Any, deep: bool = False) -> Any:
        if isinstance(node, yaml.MappingNode):
            seen: dict[Any, Any] = {}
            for key_node, _ in node.value:
                if key_node.tag == _MERGE_TAG:
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    first = seen.setdefault(key, key_node)
                except TypeError:  # an unhashable key: the base class reports it
                    continue
                if first is not key_node:
                    raise DuplicateKey(
                        None,
                        None,
                        f"duplicate key {key!r} (first on line {first.start_mark.line + 1});"
                        " a key appears once in a mapping",
                        key_node.start_mark,
                    )
        return super().construct_mapping(node, deep=deep)


# YAML 1.2 reads 2e4 and 1.0e7 as numbers; PyYAML follows YAML 1.1, which needs a dot and a
# sign in the exponent (1.0e+7) and reads the rest as text. Configs are strict (a string
# is never converted to a number), so the 1.2 spelling is resolved here, as users write it.
UniqueKeyLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)

#: The loader of configs and ``--set`` values: safe (plain data only), unique keys,
#: YAML 1.2 exponents (``2e4``) as numbers.
SAFE_LOADER = UniqueKeyLoader
#: Deepest nesting of mappings and lists in a config.
MAX_DEPTH = 32
#: Most values (mappings, lists and scalars, YAML aliases expanded) in a config.
MAX_VALUES = 100_000


def read_text(path: Path) -> str:
    """The text of a config file: UTF-8 (a UTF-8 or UTF-16/32 byte-order mark is honoured).

    Raises:
        ConfigError: unreadable, larger than `MAX_CONFIG_BYTES`, binary or not UTF-8.
    """
    try:
        size = path.stat().st_size
        if size > MAX_CONFIG_BYTES:
            raise ConfigError(
                path.name, None, f"is {size} bytes; a config has at most {MAX_CONFIG_BYTES}"
            )
        raw = path.read_bytes()
    except OSError as err:
        raise ConfigError(path.name, None, f"cannot read: {err.strerror or err}") from err
    boms = (
        (codecs.BOM_UTF32_LE, "utf-32"),
        (codecs.BOM_UTF32_BE, "utf-32"),
        (codecs.BOM_UTF8, "utf-8-sig"),
        (codecs.BOM_UTF16_LE, "utf-16"),
        (codecs.BOM_UTF16_BE, "utf-16"),
    )
    encoding = next((enc for bom, enc in boms if raw.startswith(bom)), "utf-8")
    try:
        text = raw.decode(encoding)
    except UnicodeDecodeError as err:
        raise ConfigError(
            path.name,
            None,
            f"is not {encoding.upper()} text (byte 0x{raw[err.start]:02x} at offset"
            f" {err.start}); a config is a YAML text file, saved as UTF-8",
        ) from None
    if "\x00" in text:
        raise ConfigError(path.name, None, "holds NUL characters: a binary file, not a YAML config")
    return text


_OPENS = (yaml.BlockMappingStartToken, yaml.BlockSequenceStartToken,
          yaml.FlowMappingStartToken, yaml.FlowSequenceStartToken)  # fmt: skip
_CLOSES = (yaml.BlockEndToken, yaml.FlowMappingEndToken, yaml.FlowSequenceEndToken)


def nesting_error(file: str, field: str | None = None, line: int | None = None) -> ConfigError:
    """The error for a config nested deeper than `MAX_DEPTH`, with how to fix the file."""
    where = f" (line {line})" if line is not None else ""
    return ConfigError(
        file,
        field,
        f"is nested deeper than {MAX_DEPTH} levels{where}; a geosyn config nests a few"
        " levels (section, list, entry): flatten the deep lists or mappings",
    )


def check_nesting(text: str, file: str, field: str | None = None) -> None:
    """Refuse YAML text nested deeper than `MAX_DEPTH`; called when a parse failed.

    A parser may stop at a nesting limit of its own (libyaml's, Python's recursion) before
    geosyn's `check_structure` sees the data; this counts the nesting in PyYAML's
    pure-Python token stream (no depth limit, no recursion) so that the error is geosyn's,
    whoever detected it. Other syntax errors are left to the caller.

    Raises:
        ConfigError: the nesting goes deeper than `MAX_DEPTH` levels.
    """
    depth = 0
    try:
        for token in yaml.scan(text, Loader=yaml.SafeLoader):
            if isinstance(token, _OPENS):
                depth += 1
                if depth > MAX_DEPTH:
                    raise nesting_error(file, field, token.start_mark.line + 1)
            elif isinstance(token, _CLOSES):
                depth -= 1
    except yaml.YAMLError:
        return


def check_structure(data: Any, file: str) -> None:
    """Refuse configs nested deeper than `MAX_DEPTH` or larger than `MAX_VALUES`.

    Iterative, and it stops counting at the limit, so YAML aliases that expand to
    billions of values ("billion laughs") are refused in bounded time.

    Raises:
        ConfigError: the first limit exceeded.
    """
    stack: list[tuple[Any, int]] = [(data, 0)]
    count = 0
    while stack:
        node, depth = stack.pop()
        count += 1
        if count > MAX_VALUES:
            raise ConfigError(
                file, None, f"holds more than {MAX_VALUES} values (YAML aliases expanded)"
            )
        if isinstance(node, (dict, list)):
            if depth >= MAX_DEPTH:
                raise nesting_error(file)
            children = node.values() if isinstance(node, dict) else node
            stack.extend((child, depth + 1) for child in children)


#: Default resource limits of one run; each can be raised with the environment variable
#: ``GEOSYN_MAX_<NAME>`` (e.g. ``GEOSYN_MAX_TICKS=5000000``), checked before anything runs.
LIMITS: dict[str, int] = {
    # control ticks of one simulated run (any ``duration`` / ``simulation.control_dt``).
    # A bound on disk and time, not on memory: a run longer than 8,192 ticks spools its
    # log to disk (`geosyn.sim.log_spool`) and holds one chunk of it in memory (4.8 MB for
    # a 7-DoF arm; a 600 s planar2 run peaks at the same RSS as a 60 s one). At this limit
    # a 7-DoF arm's run takes 0.58 GB of spool (584 B per tick, freed when the run's
    # results are) and writes at most 1.2 GB of CSV (`geosyn.experiments.results.data.
    # log_size`, measured figures there); simulating it takes minutes.
    "ticks": 1_000_000,
}


def limit(name: str) -> int:
    """The limit ``name`` of `LIMITS`, or ``$GEOSYN_MAX_<NAME>`` if set to an integer.

    Raises:
        ConfigError: the environment variable is set but not a positive integer.
    """
    var = f"GEOSYN_MAX_{name.upper()}"
    text = os.environ.get(var)
    if text is None:
        return LIMITS[name]
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise ConfigError(var, None, f"must be a positive integer, got {text!r}")
    return value


def _durations(node: Any, path: str) -> Iterable[tuple[str, float]]:
    """Every number under a key named ``duration`` (or in a list there), with its path."""
    if isinstance(node, dict):
        for key, value in node.items():
            sub = f"{path}.{key}" if path else str(key)
            if key == "duration":
                values = value if isinstance(value, list) else [value]
                for i, v in enumerate(values):
                    if isinstance(v, (int, float)) and not isinstance(v, bool):
                        yield (sub if not isinstance(value, list) else f"{sub}.{i}"), float(v)
            else:
                yield from _durations(value, sub)
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from _durations(value, f"{path}.{i}")


def resource_errors(cfg: ExperimentConfig) -> list[tuple[str, str]]:
    """Settings that would allocate or run far beyond what a run needs (resource bombs).

    Every ``duration`` of the config (simulation, reference, procedure parameters) is at
    most ``limit("ticks")`` control ticks; a latency is shorter than the run.
    """
    dt = cfg.simulation.control_dt
    max_ticks = limit("ticks")
    data = cfg.model_dump(mode="json")
    for field, seconds in _durations(data, ""):
        ticks = seconds / dt
        if ticks > max_ticks:
            return [
                (
                    field,
                    f"{seconds:g} s at simulation.control_dt={dt:g} s is {ticks:.3g} control"
                    f" ticks, more than the limit of {max_ticks}; shorten it, or raise the"
                    f" limit with GEOSYN_MAX_TICKS={math.ceil(ticks)} if that is intended",
                )
            ]
    run_ticks = cfg.simulation.duration / dt
    for i, d in enumerate(data.get("disturbances") or []):
        if d.get("type") != "latency":
            continue
        if d.get("ticks") is not None and d["ticks"] > run_ticks:
            return [
                (
                    f"disturbances.{i}.ticks",
                    f"{d['ticks']} ticks is longer than the run ({run_ticks:.0f} ticks of"
                    f" {dt:g} s); the controller would never see a state",
                )
            ]
        if d.get("seconds") is not None and d["seconds"] > cfg.simulation.duration:
            return [
                (
                    f"disturbances.{i}.seconds",
                    f"{d['seconds']:g} s is longer than the run ({cfg.simulation.duration:g} s);"
                    " the controller would never see a state",
                )
            ]
    return []


__all__ = [
    "LIMITS",
    "MAX_CONFIG_BYTES",
    "MAX_DEPTH",
    "MAX_VALUES",
    "SAFE_LOADER",
    "DuplicateKey",
    "check_structure",
    "limit",
    "read_text",
    "resource_errors",
]
