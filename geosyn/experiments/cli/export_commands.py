"""``geosyn export CONFIG_OR_ROBOT --controller NAME --out DIR``: one controller of an
experiment (or a built-in robot's `geosyn init` experiment) as a self-contained C library
(`geosyn.export.export_controller`). Listed in ``COMMANDS`` for `geosyn.experiments.cli`.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import yaml

from geosyn.experiments.cli.registry import Command
from geosyn.experiments.errors import ConfigError


def _robot_config(robot_name: str, controller: str) -> Any:
    """The `geosyn init` experiment of a built-in robot, with one controller section of
    type ``controller`` (its defaults)."""
    from geosyn.experiments.cli.schema_commands import template
    from geosyn.experiments.config.loader import validate_config

    data = yaml.safe_load(template("export", robot_name))
    data["controllers"] = [{"type": controller}]
    return validate_config(data, f"{robot_name} (built-in robot)")


def export_from_config(source: str, controller: str, out: str | Path, force: bool = False) -> Any:
    """Export the controller ``controller`` (its label or type) of an experiment.

    Args:
        source: a YAML experiment file, a built-in experiment name, or a built-in robot
            (then the `geosyn init` experiment with one ``controller`` section, defaults).
        controller: label or type of the controller section.
        out: export directory. force: replace a non-empty one.

    Returns:
        The `geosyn.export.ExportResult`.

    Raises:
        ConfigError: unknown source or controller, or a reference the export cannot build.
        ExportError: the export failed.
    """
    from geosyn.experiments.config.loader import builtin_names, load_config
    from geosyn.experiments.run import build as B
    from geosyn.export import export_controller
    from geosyn.robots import BUILTINS

    is_file = Path(source).suffix.lower() in (".yaml", ".yml")
    if not is_file and source not in builtin_names() and source in BUILTINS:
        cfg, file = _robot_config(source, controller), source
    else:
        cfg, path = load_config(source)
        file = path.name
    labels = cfg.controller_labels()
    matches = [i for i, c in enumerate(cfg.controllers) if controller in (labels[i], c.type)]
    if not matches:
        raise ConfigError(
            file, "controllers", f"no controller {controller!r}; available: {', '.join(labels)}"
        )
    if cfg.reference is None or cfg.reference.type not in ("log", "combination"):
        kind = None if cfg.reference is None else cfg.reference.type
        raise ConfigError(
            file, "reference", f"type {kind!r} cannot be exported; use log or combination"
        )
    robot = B.build_robot(cfg)
    metric = B.build_metric(cfg, robot)
    ref, _ = B.build_reference(cfg, metric, B.build_synergies(cfg, metric, robot))
    section = cfg.controllers[matches[0]]
    ctl = B.build_controller(section, robot, metric, cfg.simulation.control_dt)
    return export_controller(robot, ctl, out, reference=ref, overwrite=force)


def _export_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "source",
        metavar="CONFIG_OR_ROBOT",
        help="experiment YAML or built-in name, or a built-in robot (its geosyn init experiment)",
    )
    p.add_argument(
        "--controller",
        required=True,
        metavar="NAME",
        help="label or type of the controller (computed_torque, riemannian_pd)",
    )
    p.add_argument("--out", required=True, metavar="DIR", help="export directory")
    p.add_argument("--force", action="store_true", help="write into a non-empty DIR")


def cmd_export(args: argparse.Namespace) -> int:
    res = export_from_config(args.source, args.controller, args.out, args.force)
    err = res.sampling_error
    print(f"exported {res.kind} for {res.robot} (nq={res.nq}) to {res.out_dir}")
    for path in (res.header, res.shared_library, res.static_library, res.cmake_config, res.readme):
        print(f"  {path}")
    print(
        f"built-in reference: {res.samples.t.size} samples; interpolation error"
        f" {err.q:.2g} rad, {err.v:.2g} rad/s, {err.a:.2g} rad/s^2"
    )
    print(f"closed loop in MuJoCo: make -C {res.out_dir} loop && (cd {res.out_dir} && ./loop)")
    return 0


COMMANDS = (
    Command(
        "export",
        cmd_export,
        "write one controller as a self-contained C library (geosyn_controller.h, .so, .a)",
        _export_arguments,
    ),
)

__all__ = ["COMMANDS", "export_from_config"]
