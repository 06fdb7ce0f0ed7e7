"""The sphere fit's disk cache shared by processes: one fit per robot on a cold cache
(`geosyn.core.cache_folder.fill_once`), a damaged entry warned and fitted again."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_codegen_lock import race_pair
from test_collision_spheres import MJCF

from geosyn.robots import load_robot
from geosyn.robots.collision_spheres import clear_sphere_cache, file_spheres, sphere_cache_dir

# Both processes fit the robot of ``folder / "two_links.xml"`` (the cache: the test's).
_WORKER = """
from geosyn.robots import load_robot
from geosyn.robots import collision_spheres as cs

cs._fit = slowed(cs._fit)
robot = load_robot(folder / "two_links.xml")
barrier()
model = cs.file_spheres(robot)
print(repr([(s.joint, s.center, s.radius) for s in model.spheres]))
"""


def test_concurrent_processes_fit_a_robot_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Two processes on an empty cache: one fit, the same spheres in both and in a fit of
    this process from the cache; no lock file left."""
    monkeypatch.setenv("GEOSYN_CACHE_DIR", str(tmp_path / "cache"))
    xml, runs = tmp_path / "two_links.xml", tmp_path / "runs.txt"
    xml.write_text(MJCF)
    outs = race_pair(_WORKER, tmp_path, runs)
    assert len(runs.read_text().split()) == 1  # one fit for both processes
    model = file_spheres(load_robot(xml))
    assert model.cached
    mine = repr([(s.joint, s.center, s.radius) for s in model.spheres])
    assert outs == [mine, mine]
    assert not list(sphere_cache_dir().glob("*.lock"))


def test_a_damaged_cache_entry_is_warned_and_fitted_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A truncated cache file: a RuntimeWarning naming it, the same spheres as the first
    fit (not read from the cache), and the file repaired."""
    monkeypatch.setenv("GEOSYN_CACHE_DIR", str(tmp_path / "cache"))
    xml = tmp_path / "two_links.xml"
    xml.write_text(MJCF)
    robot = load_robot(xml)
    first = file_spheres(robot)
    (entry,) = sphere_cache_dir().glob("spheres_*.json")
    entry.write_text(entry.read_text()[:40])
    with pytest.warns(RuntimeWarning, match=entry.name):
        again = file_spheres(robot)
    assert not again.cached and again.spheres == first.spheres
    assert file_spheres(robot).cached
    assert clear_sphere_cache() == 1
