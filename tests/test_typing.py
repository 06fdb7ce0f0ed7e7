"""Type checking is real: mypy resolves ``geosyn.*`` to the source files, so a type error
planted in any layer fails ``make lint``; ``import geosyn`` is a small typed namespace."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from test_exports import LAYERS

import geosyn

ROOT = Path(__file__).resolve().parents[1]
# One module per layer and a use of a name from the layer below it, mistyped on purpose.
PLANTED = "\n\ndef _planted() -> int:\n    return 'not an int'  # planted type error\n"


@pytest.mark.slow
def test_mypy_catches_a_planted_error_in_every_package(tmp_path: Path) -> None:
    """Copy the package, plant one error in every (sub)package's ``__init__.py`` (each
    layer and each room inside one, e.g. ``controllers/mpc/ddp``), run the project's mypy
    configuration: every planted error is reported, nothing else."""
    shutil.copytree(
        ROOT / "geosyn", tmp_path / "geosyn", ignore=shutil.ignore_patterns("__pycache__")
    )
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    planted = []
    for target in sorted((tmp_path / "geosyn").rglob("__init__.py")):
        if target.parent == tmp_path / "geosyn":
            continue
        lines = target.read_text().count("\n")
        target.write_text(target.read_text() + PLANTED)
        planted.append(f"{target.relative_to(tmp_path).as_posix()}:{lines + 4}")
    proc = subprocess.run(
        [sys.executable, "-m", "mypy", "--no-incremental"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 1, proc.stdout + proc.stderr
    errors = [line.split(": error")[0] for line in proc.stdout.splitlines() if ": error" in line]
    assert sorted(errors) == sorted(planted), proc.stdout
    assert {p.split("/")[1] for p in planted} >= set(LAYERS)


def test_import_geosyn_gives_version_and_a_small_namespace() -> None:
    assert isinstance(geosyn.__version__, str) and geosyn.__version__[0].isdigit()
    assert 5 <= len(geosyn.__all__) <= 20
    assert all(hasattr(geosyn, name) for name in geosyn.__all__)
    assert geosyn.load_robot is __import__("geosyn.robots", fromlist=["load_robot"]).load_robot
    assert (ROOT / "geosyn" / "py.typed").exists()


def test_python_dash_m_geosyn_runs_the_cli() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "geosyn", "--help"], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0 and "usage: geosyn" in proc.stdout


def test_a_layer_folder_cannot_load_under_a_second_name() -> None:
    proc = subprocess.run(
        [sys.executable, "-c", "import metrics"], cwd=ROOT, capture_output=True, text=True
    )
    assert proc.returncode == 1 and "import geosyn.metrics, not metrics" in proc.stderr
