"""The ``geosyn view`` and ``geosyn explore`` commands (browser viewers, `geosyn.experiments.viewer`).

Listed in ``COMMANDS`` for `geosyn.experiments.cli`; viser and the robot models
are imported only when a command runs.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from geosyn.experiments.cli.registry import Command


def _server_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--port", type=int, default=8080, help="TCP port (default 8080; 0: any free)")
    p.add_argument(
        "--fast",
        action="store_true",
        help="plain lighting, no shadows (for a browser without a GPU)",
    )


def _view_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("run_dir", metavar="RUN_DIR", help="a run directory written by geosyn run")
    _server_arguments(p)


def _explore_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("robot", metavar="ROBOT", help="built-in robot name or robot file")
    p.add_argument("--k", type=int, default=3, help="number of synergies (default 3)")
    _server_arguments(p)


def cmd_view(args: argparse.Namespace) -> int:
    from geosyn.experiments.config import chatter
    from geosyn.experiments.viewer import view_run

    # MuJoCo's warnings go to the run directory's MUJOCO_LOG.TXT, never the current one
    folder = Path(args.run_dir)
    with chatter.mujoco_log(folder) if folder.is_dir() else chatter.mujoco_warnings():
        viewer = view_run(args.run_dir, port=args.port, fast=args.fast)
        print(f"viewer: {viewer.url}  (Ctrl-C to stop)", flush=True)
        viewer.serve_forever()
    return 0


def cmd_explore(args: argparse.Namespace) -> int:
    from geosyn.experiments.config import chatter
    from geosyn.experiments.viewer import explore_robot

    with chatter.mujoco_warnings():  # shown as warnings; no run directory to log them in
        viewer = explore_robot(args.robot, k=args.k, port=args.port, fast=args.fast)
        print(f"viewer: {viewer.url}  (Ctrl-C to stop)", flush=True)
        viewer.serve_forever()
    return 0


COMMANDS = (
    Command(
        "view",
        cmd_view,
        "replay a run directory in the browser (scrub time, play, compare controllers)",
        _view_arguments,
    ),
    Command(
        "explore",
        cmd_explore,
        "explore a robot's geodesic synergies in the browser (a slider per weight)",
        _explore_arguments,
    ),
)

__all__ = ["COMMANDS"]
