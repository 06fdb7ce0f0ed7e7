"""What `geosyn.sim.Simulation` needs from a controller and a reference, and reads back.

A controller is any object with ``reset(q, v, t)`` and ``compute(t, q, v) -> tau``
(`ControllerLike`; `geosyn.controllers.Controller` fits); a reference has
``sample(t) -> (q, v, a)`` (`ReferenceLike`). The simulation never hands them MuJoCo.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.robots.robot import Robot
from geosyn.sim.disturbances import Disturbance


class ControllerLike(Protocol):
    """What the simulation needs from a controller (`geosyn.controllers.Controller` fits)."""

    def reset(self, q: Vector, v: Vector, t: float = 0.0) -> None: ...

    def compute(self, t: float, q: Vector, v: Vector) -> Vector: ...


class ReferenceLike(Protocol):
    """What the simulation needs from a reference (`geosyn.controllers.Reference` fits)."""

    def sample(self, t: float) -> tuple[Vector, Vector, Vector]: ...


def check_parts(
    robot: object, controller: object, disturbances: Sequence[object]
) -> tuple[Disturbance, ...]:
    """The disturbances as a tuple, once robot, controller and disturbances are checked."""
    if not isinstance(robot, Robot):
        raise InvalidArgument(f"robot must be a geosyn.robots.Robot, got {type(robot).__name__}")
    for hook in ("reset", "compute"):
        if not callable(getattr(controller, hook, None)):
            raise InvalidArgument(
                f"controller must have a {hook}() method (a geosyn Controller), got {type(controller).__name__}"
            )
    checked = []
    for i, d in enumerate(disturbances):
        if not isinstance(d, Disturbance):
            raise InvalidArgument(f"disturbances[{i}] must be a geosyn.sim.Disturbance, got {d!r}")
        checked.append(d)
    return tuple(checked)


def controller_notes(controller: object) -> tuple[str, ...]:
    """``"name: text"`` for each note in the controller's ``diagnostics.notes`` at the end
    of a run (settings it changed when built, what it modelled, what a guard did); ()
    for a controller without diagnostics."""
    notes = getattr(getattr(controller, "diagnostics", None), "notes", None)
    if not isinstance(notes, dict):
        return ()
    return tuple(f"{name}: {text}" for name, text in notes.items())


__all__ = ["ControllerLike", "ReferenceLike", "check_parts", "controller_notes"]
