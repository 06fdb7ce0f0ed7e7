"""What every config field is: its type, default, unit and meaning (``geosyn schema``).

Meanings and units come from where the defaults come from: a `Section`'s fields are
parameters of the library calls it stands for, so their documentation is the ``Args:``
(or ``Attributes:``) entry of those calls' Google docstrings, with the unit the first
``[...]`` in it. Fields that stand for no parameter (a section's ``type``, a controller's
``label``, the top-level sections, the shapes, the procedures' ``params``) are documented
in `FIELD_DOCS`. `undocumented` lists any field neither source covers (a test keeps it
empty).
"""

from __future__ import annotations

import inspect
import re
import typing
from collections.abc import Callable, Iterator
from typing import Any, Literal, NamedTuple

from pydantic import BaseModel
from pydantic.fields import FieldInfo

from geosyn.experiments.schema.docs import FIELD_DOCS, TYPE_FIELD
from geosyn.experiments.schema.section import Section


class FieldDoc(NamedTuple):
    """One documented config field.

    Attributes:
        path: dotted path in a config file (``controllers[type=qp].kp``).
        type: the accepted values, readable (``float >= 0 | list[float >= 0]``).
        default: the default as YAML text, or ``"required"``.
        unit: SI unit, ``""`` when none applies.
        meaning: one sentence.
    """

    path: str
    type: str
    default: str
    unit: str
    meaning: str


_ARG = re.compile(r"^(\*{0,2}\w+(?:, \w+)*)(?: \([^)]*\))?: (.*)$")
#: ````name``: text`` in a model's own docstring (up to the end of its paragraph).
_INLINE = re.compile(r"``(\w+)``: (.+?)(?:\n\s*\n|$)", re.S)
_UNIT = re.compile(r"\[([^\]\[`]+)\]")


def docstring_args(fn: Callable[..., Any]) -> dict[str, str]:
    """``name -> text`` of the ``Args:`` and ``Attributes:`` entries of a Google docstring
    (of ``fn`` and, for a class, of its ``__init__``)."""
    out: dict[str, str] = {}
    for obj in (fn, getattr(fn, "__init__", None)):
        doc = inspect.getdoc(obj) if obj is not None else None
        lines = (doc or "").splitlines()
        for k, line in enumerate(lines):
            if line.strip() not in ("Args:", "Attributes:"):
                continue
            indent = len(line) - len(line.lstrip()) + 4
            current = None
            for entry in lines[k + 1 :]:
                if not entry.strip() or len(entry) - len(entry.lstrip()) < indent:
                    break
                m = _ARG.match(entry[indent:])
                if m and len(entry) - len(entry.lstrip()) == indent:
                    names = m.group(1).split(", ")
                    current = names[0]
                    for name in names:
                        out.setdefault(name, m.group(2))
                elif current is not None and out.get(current) is not None:
                    out[current] += " " + entry.strip()
    return out


def _constraints(metadata: list[Any]) -> str:
    parts = []
    for m in metadata:
        for attr, sym in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")):
            value = getattr(m, attr, None)
            if value is not None:
                parts.append(f"{sym} {value}")
        for attr, sym in (("min_length", "len >="), ("max_length", "len <=")):
            value = getattr(m, attr, None)
            if value is not None:
                parts.append(f"{sym} {value}")
    return f" {', '.join(parts)}" if parts else ""


def type_name(annotation: Any) -> str:
    """A readable name of a field's accepted values."""
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin is typing.Annotated:
        inner, *meta = args
        constraint = ""
        for m in meta:
            if isinstance(m, FieldInfo):
                constraint += _constraints(m.metadata)
                if m.discriminator is not None:
                    return " | ".join(type_name(a) for a in typing.get_args(inner))
            else:
                constraint += _constraints([m])
        return type_name(inner) + constraint
    if origin is Literal:
        return " | ".join(repr(a) for a in args)
    if origin in (typing.Union, getattr(__import__("types"), "UnionType", None)):
        return " | ".join(type_name(a) for a in args)
    if origin is list:
        return f"list[{type_name(args[0])}]"
    if origin is dict:
        return f"mapping {type_name(args[0])} -> {type_name(args[1])}"
    if annotation is type(None):
        return "null"
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        kind = annotation.model_fields.get("type")
        if kind is not None:
            return f"{{type: {type_name(kind.annotation)}}}"
        return "section"
    return getattr(annotation, "__name__", str(annotation))


def _default(field: FieldInfo) -> str:
    if field.is_required():
        return "required"
    value = field.get_default(call_default_factory=True)
    if isinstance(value, BaseModel):
        return "(its defaults)"
    if value is None:
        return "null"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, str):
        return repr(value)
    return str(value)


def config_models(annotation: Any) -> list[type[BaseModel]]:
    """The config models (pydantic) an annotation may hold, unions and containers unpacked."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    out: list[type[BaseModel]] = []
    for a in typing.get_args(annotation):
        out += config_models(a)
    return out


def _section_docs(model: type[BaseModel]) -> dict[str, str]:
    docs: dict[str, str] = {}
    if issubclass(model, Section):
        for target in model.builds:
            for name, text in docstring_args(target).items():
                docs.setdefault(name, text)
    return docs


def _own_docs(model: type[BaseModel]) -> dict[str, str]:
    """Fields documented in the model's own docstring (``Attributes:`` or ````name``: ...``)."""
    docs = docstring_args(model)
    for name, text in _INLINE.findall(inspect.getdoc(model) or ""):
        docs.setdefault(name, " ".join(text.split()))
    return docs


def field_doc(model: type[BaseModel], name: str, path: str) -> FieldDoc:
    """The documentation of field ``name`` of ``model``, shown at ``path``."""
    field = model.model_fields[name]
    table = FIELD_DOCS.get(model.__name__, {})
    if name in table:
        unit, meaning = table[name]
    elif name == "type":
        unit, meaning = "", TYPE_FIELD
    else:
        param = getattr(model, "parameter_names", {}).get(name, name)
        text = _section_docs(model).get(param, "") or _own_docs(model).get(name, "")
        meaning = _first_sentence(text)
        ranges = re.compile(r"^\s*-?[\d.]+\s*,")  # "[0, 1]" is a range, not a unit
        units = [u for u in _UNIT.findall(meaning) if not ranges.match(u)]
        unit = units[0] if units and units[0] != "-" else ""
    if field.description:
        meaning = field.description
    kind = type_name(field.annotation) + _constraints(field.metadata)
    return FieldDoc(path, kind, _default(field), unit, meaning)


def _first_sentence(text: str) -> str:
    """Up to the first full stop that ends a sentence (not inside ``e.g.``)."""
    m = re.search(r"(?<!e\.g)(?<!i\.e)\.(\s|$)", text)
    return text[: m.start() + 1] if m else text


def walk(model: type[BaseModel], prefix: str = "") -> Iterator[FieldDoc]:
    """Every field of ``model`` and of the sections it holds, depth first."""
    for name, field in model.model_fields.items():
        path = f"{prefix}{name}"
        yield field_doc(model, name, path)
        subs = config_models(field.annotation)
        is_list = typing.get_origin(field.annotation) is list or any(
            typing.get_origin(a) is list for a in typing.get_args(field.annotation)
        )
        item = f"{path}[]" if is_list else path
        for sub in subs:
            kind = sub.model_fields.get("type")
            tag = typing.get_args(kind.annotation)[0] if kind is not None else None
            yield from walk(sub, f"{item}[type={tag}]." if tag else f"{item}.")


def undocumented(models: list[type[BaseModel]]) -> list[str]:
    """Paths of fields without a meaning (should be none)."""
    return [d.path for m in models for d in walk(m, f"{m.__name__}.") if not d.meaning]


__all__ = ["FieldDoc", "docstring_args", "field_doc", "type_name", "undocumented", "walk"]
