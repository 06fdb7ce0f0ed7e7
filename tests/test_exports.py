"""Every public name a package lists in ``__all__`` resolves, and layers import left to right."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

PACKAGES = [
    "geosyn.core",
    "geosyn.robots",
    "geosyn.world",
    "geosyn.metrics",
    "geosyn.metrics.shaping",
    "geosyn.synergies",
    "geosyn.controllers",
    "geosyn.sim",
    "geosyn.export",
    "geosyn.experiments",
]
LAYERS = [
    "core",
    "robots",
    "world",
    "metrics",
    "synergies",
    "controllers",
    "sim",
    "export",
    "experiments",
]
ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("name", PACKAGES)
def test_all_names_resolve(name: str) -> None:
    module = importlib.import_module(name)
    exported = getattr(module, "__all__", None)
    assert exported, f"{name} has no __all__"
    missing = [n for n in exported if not hasattr(module, n)]
    assert not missing, f"{name}.__all__ lists names that do not resolve: {missing}"
    assert len(set(exported)) == len(exported), f"{name}.__all__ has duplicates"


@pytest.mark.parametrize("layer", LAYERS)
def test_imports_go_left_to_right(layer: str) -> None:
    """A module never imports from a layer to its right (core -> ... -> experiments)."""
    allowed = set(LAYERS[: LAYERS.index(layer) + 1])
    offenders = []
    for path in sorted((ROOT / "geosyn" / layer).rglob("*.py")):
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            for mod in names:
                parts = mod.split(".")
                if parts[0] == "geosyn" and len(parts) > 1 and parts[1] not in allowed:
                    offenders.append(f"{path.relative_to(ROOT)} imports {mod}")
    assert not offenders, "\n".join(offenders)


def test_controllers_never_import_mujoco() -> None:
    for path in sorted((ROOT / "geosyn" / "controllers").rglob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            mods = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [node.module or ""]
                if isinstance(node, ast.ImportFrom)
                else []
            )
            assert not any(m.split(".")[0] == "mujoco" for m in mods), f"{path} imports mujoco"
