"""Config problems as ``(field path, reason)`` pairs and the one `ConfigError` that lists
them all: pydantic errors turned into dotted field paths, unknown keys with the closest
valid ones (difflib) and every valid key at that place, unknown ``type`` tags with the
closest allowed one."""

from __future__ import annotations

import difflib
import typing
from typing import Any, NoReturn

from pydantic import BaseModel, ValidationError

from geosyn.experiments.errors import ConfigError
from geosyn.experiments.schema.describe import config_models


def field_path(loc: tuple[Any, ...], data: Any) -> str:
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


def _model_at(root: type[BaseModel], loc: tuple[Any, ...], data: Any) -> list[type[BaseModel]]:
    """The config models an error location's parent may be (for the valid keys there)."""
    candidates: list[type[BaseModel]] = [root]
    node = data
    for item in loc[:-1]:
        node = node[item] if isinstance(node, (dict, list)) and _has(node, item) else None
        if isinstance(item, int):
            continue
        tagged = [c for c in candidates if typing.get_args(_type_of(c)) == (item,)]
        if tagged:
            candidates = tagged
            continue
        owner = next((c for c in candidates if item in c.model_fields), None)
        if owner is None:
            return []
        candidates = config_models(owner.model_fields[item].annotation)
        if len(candidates) > 1 and isinstance(node, dict) and "type" in node:
            same = [c for c in candidates if typing.get_args(_type_of(c)) == (node["type"],)]
            candidates = same or candidates
    return candidates


def _has(node: Any, item: Any) -> bool:
    if isinstance(node, dict):
        return item in node
    return isinstance(item, int) and 0 <= item < len(node)


def _type_of(model: type[BaseModel]) -> Any:
    field = model.model_fields.get("type")
    return None if field is None else field.annotation


def _unknown_key(root: type[BaseModel], loc: tuple[Any, ...], data: Any) -> str:
    """``unknown key 'x'; did you mean 'y'? valid: ...`` for an extra key at ``loc``."""
    key = str(loc[-1])
    valid = sorted({name for m in _model_at(root, loc, data) for name in m.model_fields} - {"type"})
    if not valid:
        return "unknown key (Extra inputs are not permitted)"
    close = difflib.get_close_matches(key, valid, n=3, cutoff=0.6)
    hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ";"
    return f"unknown key {key!r}{hint} valid keys here: {', '.join(valid)}"


#: pydantic error types of a value of the wrong type (strict mode: never coerced).
_STRICT_TYPES = ("float_type", "int_type", "bool_type", "string_type", "int_from_float")


def _no_coercion(msg: str, value: Any) -> str:
    """A wrong-type message that names the value and why it is not converted."""
    got = f"{msg}, got {type(value).__name__} {_short(value)}"
    if isinstance(value, str):
        try:
            float(value)
        except ValueError:
            return got
        return f"{got}: a quoted number is text, never converted; write it without quotes"
    if isinstance(value, bool):
        return f"{got}: a boolean is not a number (no true -> 1 conversion)"
    if isinstance(value, float) and msg.endswith("integer"):
        return f"{got}: write a whole number without a decimal point"
    return got


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def validation_errors(
    err: ValidationError, data: Any, root: type[BaseModel], prefix: str = ""
) -> list[tuple[str, str]]:
    """Every problem of a pydantic error as ``(field path, reason)``, one per field."""
    out: dict[str, str] = {}
    for e in err.errors():
        loc = tuple(e["loc"])
        field = field_path(loc, data)
        if prefix:
            field = prefix if field == "<top level>" else f"{prefix}.{field}"
        msg = e["msg"]
        if e["type"] == "extra_forbidden":
            msg = _unknown_key(root, loc, data)
        elif e["type"] == "union_tag_invalid":
            ctx = e.get("ctx", {})
            tags = [t.strip(" '") for t in str(ctx.get("expected_tags", "")).split(",")]
            close = difflib.get_close_matches(str(ctx.get("tag")), tags, n=1, cutoff=0.6)
            hint = f"; did you mean {close[0]!r}?" if close else ";"
            msg = f"unknown type {ctx.get('tag')!r}{hint} allowed: {ctx.get('expected_tags')}"
        elif e["type"] == "union_tag_not_found":
            msg = f"missing 'type'; allowed: {e.get('ctx', {}).get('expected_tags', '')}"
        elif e["type"] in _STRICT_TYPES and "input" in e:
            msg = _no_coercion(msg, e["input"])
        if msg.startswith("Value error, "):
            msg = msg[len("Value error, ") :]
        if field in out:  # one reason per field (a union reports one per member)
            continue
        out[field] = msg
    return list(out.items())


def raise_problems(file: str, problems: list[tuple[str, str]]) -> NoReturn:
    """Raise one `ConfigError` listing every ``(field, reason)`` problem, the first one
    as its ``field``, the others appended to its reason (``; other.field: reason``)."""
    (field, reason), *rest = problems
    if rest:
        reason += "; " + "; ".join(f"{f}: {r}" for f, r in rest)
        reason += f" ({len(problems)} problems)"
    raise ConfigError(file, field, reason)


__all__ = ["field_path", "raise_problems", "validation_errors"]
