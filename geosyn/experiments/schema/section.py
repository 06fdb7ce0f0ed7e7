"""The base classes of the config models and their defaults taken from signatures.

A config section that stands for library calls (a controller, a metric term, a
disturbance, the simulation, ...) is a `Section`: it names those callables in ``builds``
and takes each default from their signatures with `python_defaults`, so the YAML default
and the Python default are the same value by construction. A section default that the
callables cannot supply (their argument is required) is given to `python_defaults`
explicitly; it may not shadow a Python default (the config could then disagree).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict


class Strict(BaseModel):
    """Base of every config model: unknown keys are errors, and so is every value that
    only a coercion would make fit (pydantic's strict mode): a string where a number or
    a boolean belongs (``kp: '900'``), a boolean where a number belongs (``seed: true``),
    a float where an integer belongs (``substeps: 2.0``). An integer is a valid float.
    No float field takes ``inf`` or ``nan`` (a field where "never" or "no limit" makes
    sense says so with ``None``)."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


def python_defaults(*targets: Callable[..., Any], **config_only: Any) -> dict[str, Any]:
    """The default of every parameter of ``targets``, as config values.

    Args:
        targets: the callables a config section stands for; for a name that several of
            them take, the first one's default is used (tests check that they agree).
        config_only: defaults of parameters that every target requires (no Python default
            exists to follow), e.g. the gains of a controller.

    Returns:
        name -> default; tuples become lists (a YAML sequence).

    Raises:
        TypeError: a ``config_only`` name is not a parameter of a target, or has a Python
            default (the config would restate it, and could disagree).
    """
    out: dict[str, Any] = {}
    params: set[str] = set()
    for target in targets:
        for name, p in inspect.signature(target).parameters.items():
            params.add(name)
            if p.default is not inspect.Parameter.empty and name not in out:
                out[name] = list(p.default) if isinstance(p.default, tuple) else p.default
    for name, value in config_only.items():
        if name not in params or name in out:
            where = ", ".join(t.__qualname__ for t in targets)
            problem = "is not a parameter" if name not in params else "has a Python default"
            raise TypeError(f"config-only default {name!r} {problem} of {where}")
        out[name] = value
    return out


class Section(Strict):
    """A config section standing for library calls (see the module doc).

    Class attributes:
        builds: the callables whose parameters the section's fields are; the first is
            the one `kwargs` is for.
        parameter_names: field -> the parameter it sets, where the names differ.
        to_python: field -> conversion of its config value to the argument the callable
            takes (e.g. ``None`` -> ``inf``); identity for the others.
    """

    builds: ClassVar[tuple[Callable[..., Any], ...]] = ()
    parameter_names: ClassVar[dict[str, str]] = {}
    to_python: ClassVar[dict[str, Callable[[Any], Any]]] = {}

    def kwargs(self) -> dict[str, Any]:
        """Keyword arguments of ``builds[0]`` given by this section (its fields that are
        parameters of it), converted by `to_python`."""
        params = inspect.signature(self.builds[0]).parameters
        out = {}
        for name in type(self).model_fields:
            param = self.parameter_names.get(name, name)
            if param in params:
                out[param] = self.to_python.get(name, _identity)(getattr(self, name))
        return out


def _identity(value: Any) -> Any:
    return value


__all__ = ["Section", "Strict", "python_defaults"]
