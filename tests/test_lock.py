"""The committed lock (uv.lock) and pyproject.toml describe the same dependencies.

`make run` / `make test` install from uv.lock with ``uv sync --locked`` (which refuses a
stale lock at install time); this test says the same thing without network or uv, so a
dependency added to one file and not the other fails the suite, naming it.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import tomllib
from packaging.requirements import Requirement
from packaging.specifiers import SpecifierSet
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
LOCK = tomllib.loads((ROOT / "uv.lock").read_text())
#: name -> the [[package]] entry of uv.lock
LOCKED = {canonicalize_name(p["name"]): p for p in LOCK["package"]}
ROOT_ENTRY = LOCKED["geosyn"]

Key = tuple[str, str | None, str]  # (name, extra or None, specifier)


def _declared() -> set[Key]:
    """pyproject.toml's requirements as (name, extra, specifier)."""
    project = PYPROJECT["project"]
    out: set[Key] = set()
    groups: list[tuple[str | None, list[str]]] = [(None, project["dependencies"])]
    groups += list(project.get("optional-dependencies", {}).items())
    for extra, reqs in groups:
        for text in reqs:
            req = Requirement(text)
            out.add((canonicalize_name(req.name), extra, str(SpecifierSet(str(req.specifier)))))
    return out


def _locked_requirements() -> set[Key]:
    """The requirements uv.lock was resolved from (its ``requires-dist`` of geosyn)."""
    out: set[Key] = set()
    for item in ROOT_ENTRY["metadata"]["requires-dist"]:
        marker = item.get("marker", "")
        m = re.fullmatch(r"extra == '([^']+)'", marker)
        if marker and m is None:
            raise AssertionError(f"uv.lock: unexpected marker {marker!r} on {item['name']}")
        spec = str(SpecifierSet(item.get("specifier", "")))
        out.add((canonicalize_name(item["name"]), m.group(1) if m else None, spec))
    return out


def test_lock_and_pyproject_name_the_same_requirements() -> None:
    declared, locked = _declared(), _locked_requirements()
    only_pyproject = sorted(declared - locked, key=str)
    only_lock = sorted(locked - declared, key=str)
    assert not only_pyproject and not only_lock, (
        "uv.lock is stale: run `make lock`.\n"
        f"  in pyproject.toml only: {only_pyproject}\n  in uv.lock only: {only_lock}"
    )


def test_lock_resolves_python_and_every_make_test_extra() -> None:
    assert LOCK["requires-python"] == PYPROJECT["project"]["requires-python"]
    makefile = (ROOT / "Makefile").read_text()
    m = re.search(r"^EXTRAS\s*:=\s*(.+)$", makefile, re.MULTILINE)
    assert m, "Makefile has no EXTRAS line"
    extras = m.group(1).split()
    assert set(extras) <= set(PYPROJECT["project"]["optional-dependencies"]), extras
    assert set(extras) <= set(ROOT_ENTRY["optional-dependencies"]), extras


@pytest.mark.parametrize("key", sorted(_declared(), key=str), ids=lambda k: f"{k[0]}[{k[1]}]")
def test_every_locked_version_meets_pyproject_bound(key: Key) -> None:
    """Each requirement is locked (with a hash to check) at a version within its bounds."""
    name, _, spec = key
    assert name in LOCKED, f"{name} is required by pyproject.toml but not in uv.lock"
    entry = LOCKED[name]
    assert Version(entry["version"]) in SpecifierSet(spec), (name, entry["version"], spec)
    artefacts = [*entry.get("wheels", []), *([entry["sdist"]] if "sdist" in entry else [])]
    assert artefacts and all(a.get("hash", "").startswith("sha256:") for a in artefacts), name


def test_every_locked_package_is_reachable_from_geosyn() -> None:
    """No orphan in the lock: every package is geosyn or a dependency of one reached."""
    seen, todo = {"geosyn"}, ["geosyn"]
    while todo:
        entry = LOCKED[todo.pop()]
        deps = list(entry.get("dependencies", []))
        for group in entry.get("optional-dependencies", {}).values():
            deps += group
        for dep in deps:
            name = canonicalize_name(dep["name"])
            if name not in seen:
                seen.add(name)
                todo.append(name)
    assert set(LOCKED) == seen, sorted(set(LOCKED) - seen)
