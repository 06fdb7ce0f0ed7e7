"""Every URDF that example-robot-data ships, by name (``load_robot("xarm7")``).

A name is the file's stem in lower case (``-`` becomes ``_``); stems found in two folders
are prefixed with their folder (``anymal_b_simple_anymal``). The robot is the file as it
is: its joints, its effort limits, no added armature (the curated built-ins ``panda``,
``talos_arm`` and ``ur5`` add theirs). Robots that walk, fly or roll (a floating base in
the real world) load with a free-flyer root joint (configuration on SE(3) x R^n,
`geosyn.robots.floating`), or welded at their root link with ``fixed_base=True``,
recorded in ``Robot.base``; files with slightly unphysical inertias load with a
`RobotWarning` naming the link.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

from geosyn.robots.errors import RobotFileError, RobotWarning
from geosyn.robots.files import example_robot_data_dir, load_file
from geosyn.robots.robot import Robot

#: example-robot-data folders whose robots have a floating base (legged, humanoid,
#: flying or mobile robots); they load floating unless ``fixed_base=True``.
FLOATING_FOLDERS = frozenset(
    {
        "a1_description",
        "alex_description",
        "alexander_description",
        "anymal_b_simple_description",
        "anymal_c_simple_description",
        "b1_description",
        "bolt_description",
        "borinot_description",
        "cassie_description",
        "centauro_description",
        "g1_description",
        "go1_description",
        "go2_description",
        "hector_description",
        "hextilt_description",
        "human_description",
        "hyq_description",
        "icub_description",
        "iris_description",
        "laikago_description",
        "pr2_description",
        "quadruped_description",
        "romeo_description",
        "simple_humanoid_description",
        "solo_description",
        "talos_data",
        "tiago_description",
        "tiago_pro_description",
    }
)


class CatalogEntry(NamedTuple):
    """One URDF of example-robot-data."""

    name: str
    relative_path: str  # below `example_robot_data_dir`
    floating: bool  # the robot has a floating base in the real world


@functools.cache
def catalog() -> dict[str, CatalogEntry]:
    """The URDFs of example-robot-data by name; empty when the package is missing."""
    try:
        root = example_robot_data_dir()
    except RobotFileError:
        return {}
    paths = sorted(root.rglob("*.urdf"))
    stems: dict[str, list[Path]] = {}
    for p in paths:
        stems.setdefault(p.stem.lower().replace("-", "_"), []).append(p)
    out: dict[str, CatalogEntry] = {}
    for stem, group in stems.items():
        for p in group:
            rel = p.relative_to(root)
            folder = rel.parts[0]
            name = stem if len(group) == 1 else f"{folder.removesuffix('_description')}_{stem}"
            out[name] = CatalogEntry(name, rel.as_posix(), folder in FLOATING_FOLDERS)
    return out


def load_catalog_robot(entry: CatalogEntry, **options: object) -> Robot:
    """Load one catalog URDF; see the module docstring.

    Args:
        entry: the catalog entry.
        **options: ``fixed_base`` (welds a floating robot's root link to the world) and
            anything `geosyn.robots.files.load_file` accepts.

    Raises:
        FloatingBaseError: a floating-base robot with joint couplings (load it with
            ``fixed_base=True``).
    """
    fixed_base = bool(options.pop("fixed_base", False))
    if entry.floating and not fixed_base:
        options["floating_base"] = True
    elif entry.floating:
        options.setdefault("base", "floating base fixed at its root link (fixed_base=True)")
        warnings.warn(
            f"{entry.name!r}: its floating base is fixed at the root link (fixed_base=True)",
            RobotWarning,
            stacklevel=3,
        )
    options.setdefault("name", entry.name)
    options.setdefault("inertia_check", "warn")
    return load_file(example_robot_data_dir() / entry.relative_path, **options)


def catalog_builders() -> dict[str, Callable[..., Robot]]:
    """``{name: builder}`` for every catalog URDF."""
    return {name: functools.partial(load_catalog_robot, entry) for name, entry in catalog().items()}
