"""The procedure interface and registry: one registered class per experiment ``kind``.

A procedure computes (``run``), reduces (``summarize``) and draws (``plot``). ``run``
returns the arrays saved in ``results.npz``; ``summarize`` and ``plot`` read only those
arrays and the config, so ``geosyn report RUN_DIR`` regenerates summary and plots
without re-running the experiment.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel

from geosyn.experiments.run.build import sim_view
from geosyn.experiments.run.run_metrics import (
    DEFAULT_THRESHOLD,
    disturbance_windows,
    standard_metrics,
)
from geosyn.experiments.run.scene import BuiltScene
from geosyn.experiments.schema import ExperimentConfig, Strict
from geosyn.robots import Robot


class NoParams(Strict):
    """A procedure without parameters: ``params`` must be empty."""


@dataclass
class RunContext:
    """What a procedure receives.

    Attributes:
        config: the validated config.
        params: the procedure's validated ``Params``.
        scene: the run's world, built once from the config (robot, obstacles, payloads,
            contact, cameras; `geosyn.experiments.run.scene`): hand it to the metric, the
            controllers, the simulation, never rebuild it from the config.
        out_dir: where to write extra files (the run's temporary directory).
        video: render videos (``--video`` or ``outputs.video``).
        progress: ``progress(description, total) -> advance()``, a progress-bar factory.
    """

    config: ExperimentConfig
    params: Any
    scene: BuiltScene
    out_dir: Path
    video: bool = False
    progress: Callable[[str, int], Callable[[], None]] = field(
        default=lambda description, total: lambda: None
    )

    @property
    def robot(self) -> Robot:
        """The robot of the run (``scene.robot``)."""
        return self.scene.robot


class Procedure(ABC):
    """One kind of experiment.

    Class attributes:
        kind: the name used in configs (``kind: ...``).
        description: one line for ``geosyn list``.
        Params: pydantic model of the ``params`` section (unknown keys rejected).
        units: unit of each summary metric of its own, for the tables (the standard
            metrics' units, `geosyn.experiments.run.run_metrics.UNITS`, apply without listing them).
    """

    kind: ClassVar[str]
    description: ClassVar[str]
    Params: ClassVar[type[BaseModel]] = NoParams
    #: Unit of each summary metric (the name after the last dot), shown in tables.
    units: ClassVar[dict[str, str]] = {}
    #: The config sections the procedure reads (`SECTIONS` names); None: not declared.
    #: A run logs every other section the config sets (it has no effect).
    sections: ClassVar[tuple[str, ...] | None] = None

    @classmethod
    def check(cls, cfg: ExperimentConfig, params: Any, robot: Robot) -> list[tuple[str, str]]:
        """Procedure-specific config problems as ``(field path, reason)``; none by default."""
        return []

    @abstractmethod
    def run(self, ctx: RunContext) -> dict[str, np.ndarray]:
        """Compute the experiment; returns the arrays saved in ``results.npz``."""

    @abstractmethod
    def summarize(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray]
    ) -> dict[str, float]:
        """Flat scalar summary (``row.metric`` keys make a table in summary.md)."""

    def plot(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray], out_dir: Path
    ) -> list[Path]:
        """Write PNG plots into ``out_dir``; returns their paths (none by default)."""
        return []

    def run_rows(self, cfg: ExperimentConfig, results: dict[str, np.ndarray]) -> dict[str, str]:
        """Summary row of each stored closed-loop run: ``{run prefix: row name}``.

        By default every stored run (see `geosyn.experiments.run.build.sim_arrays`) is its own
        row, named by its prefix; procedures whose rows have other names override this.
        """
        return {p: p for p in stored_runs(results)}

    def full_summary(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray]
    ) -> dict[str, float]:
        """`summarize`, then the standard metrics of every stored run
        (`geosyn.experiments.run.run_metrics.standard_metrics`) that the procedure's own summary
        does not already give (its own metrics, the claims, win)."""
        out = dict(self.summarize(cfg, params, results))
        windows = disturbance_windows(cfg.disturbances)
        threshold = float(getattr(params, "threshold", DEFAULT_THRESHOLD))
        for prefix, row in self.run_rows(cfg, results).items():
            run = sim_view(results, prefix)
            metrics = standard_metrics(run, cfg.simulation.control_dt, windows, threshold)
            for name, value in metrics.items():
                out.setdefault(f"{row}.{name}", value)
        return out


def stored_runs(results: dict[str, np.ndarray]) -> list[str]:
    """Prefixes of the closed-loop runs stored in ``results`` (in storage order)."""
    tail = "__tracking_error"
    return [k[: -len(tail)] for k in results if k.endswith(tail)]


#: Sections of an experiment file a procedure may read (``name``, ``kind``, ``seed`` and
#: ``description`` always apply).
SECTIONS = (
    "robot",
    "metric",
    "scene",
    "stance",
    "synergies",
    "reference",
    "controllers",
    "disturbances",
    "simulation",
    "outputs",
    "params",
)


def ignored_sections(cfg: ExperimentConfig, proc: type[Procedure]) -> list[str]:
    """Sections the config sets (not at their defaults) that ``proc`` does not read."""
    if proc.sections is None:
        return []
    defaults = ExperimentConfig.model_fields
    out = []
    for name in SECTIONS:
        if name in proc.sections:
            continue
        value = getattr(cfg, name)
        default = defaults[name].get_default(call_default_factory=True)
        if value != default:
            out.append(name)
    return out


#: Registered procedures by kind.
PROCEDURES: dict[str, type[Procedure]] = {}


def register(cls: type[Procedure]) -> type[Procedure]:
    """Class decorator: register a procedure under ``cls.kind``."""
    if cls.kind in PROCEDURES and PROCEDURES[cls.kind] is not cls:
        raise ValueError(f"procedure kind {cls.kind!r} is registered twice")
    PROCEDURES[cls.kind] = cls
    return cls


def check_required(cfg: ExperimentConfig, *sections: str) -> list[tuple[str, str]]:
    """``(section, "required by kind ...")`` for each missing/empty config section."""
    out = []
    for s in sections:
        value = getattr(cfg, s)
        if value is None or (isinstance(value, list) and not value):
            out.append((s, f"required by kind {cfg.kind!r}"))
    return out
