"""The disk cache of the collocation's per-node functions (issue 22): what is read back
evaluates as the freshly built graph (reference: `node_functions` built in the test), and
the key follows the spheres."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.geodesic import collocation_nlp as nlp
from geosyn.metrics.geodesic.collocation_parts import node_functions
from geosyn.metrics.shaping.obstacle import ObstacleTerm
from geosyn.robots import CollisionSphere, Robot
from geosyn.world import Box


def test_cached_node_functions_equal_fresh_ones(panda: Robot, tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("GEOSYN_CACHE_DIR", str(tmp_path))
    metric = KineticEnergyMetric(panda)
    spheres = [CollisionSphere("panda_joint4", (0.0, 0.0, 0.0), 0.08),
               CollisionSphere("panda_joint7", (0.0, 0.0, 0.1), 0.06)]  # fmt: skip
    term = ObstacleTerm([Box((0.5, 0.0, 0.4), (0.1, 0.2, 0.3))], capacity=1, spheres=spheres)
    term.bind(panda)
    nlp.clear_node_function_cache()
    built = nlp.per_node_functions(metric, term, True, 1000.0, "none")
    assert len(list((tmp_path / "nlp").glob("nodefuns_*.json"))) == 1
    nlp._MEMORY.clear()  # the next call reads the disk
    read = nlp.per_node_functions(metric, term, True, 1000.0, "none")
    assert read[2] is not built[2]
    fresh = node_functions(metric, term, True, 1000.0)
    rng = np.random.default_rng(2)
    pc = term.parameter_values()
    for _ in range(3):
        qa, qb = panda.random_q(rng), panda.random_q(rng)
        lam = rng.uniform(0.1, 1.0, 1)
        np.testing.assert_allclose(np.asarray(read[1](qa, qb, [])[2]),
                                   np.asarray(fresh[1](qa, qb, [])[2]), rtol=1e-12, atol=1e-12)  # fmt: skip
        np.testing.assert_allclose(float(read[2](qa, pc)), float(fresh[2](qa, pc)), atol=1e-12)
        np.testing.assert_allclose(np.asarray(read[4](qa, pc, lam)),
                                   np.asarray(fresh[4](qa, pc, lam)), rtol=1e-9, atol=1e-12)  # fmt: skip
    other = ObstacleTerm((), capacity=1, spheres=spheres[:1]).bind(panda)
    key = nlp.node_function_key(metric, term, True, 1000.0)
    assert key != nlp.node_function_key(metric, other, True, 1000.0)
    assert nlp.node_function_key(metric, term, False, 1000.0) != key
    assert nlp.clear_node_function_cache() == 1


def test_a_damaged_entry_is_warned_and_built_again(panda: Robot, tmp_path, monkeypatch) -> None:
    """A truncated cache file: a RuntimeWarning naming it, functions evaluating as a fresh
    build (1e-12), and the file repaired (read back silently)."""
    monkeypatch.setenv("GEOSYN_CACHE_DIR", str(tmp_path))
    metric = KineticEnergyMetric(panda)
    nlp.clear_node_function_cache()
    nlp.per_node_functions(metric, None, False, None, "none")
    (entry,) = (tmp_path / "nlp").glob("nodefuns_*.json")
    entry.write_text(entry.read_text()[:100])
    nlp._MEMORY.clear()
    with pytest.warns(RuntimeWarning, match=entry.name):
        again = nlp.per_node_functions(metric, None, False, None, "none")
    fresh = node_functions(metric, None, False, None)
    rng = np.random.default_rng(4)
    qa, qb = panda.random_q(rng), panda.random_q(rng)
    np.testing.assert_allclose(np.asarray(again[1](qa, qb, [])[2]),
                               np.asarray(fresh[1](qa, qb, [])[2]), rtol=1e-12, atol=1e-12)  # fmt: skip
    nlp._MEMORY.clear()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        nlp.per_node_functions(metric, None, False, None, "none")
    assert nlp.clear_node_function_cache() == 1


# Both processes build the planar arm's per-node functions (the cache: ``folder``).
_WORKER = """
from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.geodesic import collocation_nlp as nlp
from geosyn.robots import load_robot

nlp._build_node_functions = slowed(nlp._build_node_functions)
metric = KineticEnergyMetric(load_robot("planar2"))
barrier()
funcs = nlp.per_node_functions(metric, None, False, None, "none")
print(repr(float(funcs[0]([0.1, 0.2], [0.3, -0.1], [])[0])))
"""


def test_concurrent_processes_build_the_node_functions_once(tmp_path, monkeypatch) -> None:
    """Two processes on an empty cache: one build, the same segment energy in both as in
    this process's fresh build (1e-15 relative); no lock file left."""
    from test_codegen_lock import race_pair

    monkeypatch.setenv("GEOSYN_CACHE_DIR", str(tmp_path))
    runs = tmp_path / "runs.txt"
    outs = race_pair(_WORKER, tmp_path, runs)
    assert len(runs.read_text().split()) == 1  # one build for both processes
    from conftest import get_metric

    fresh = node_functions(get_metric("planar2"), None, False, None)
    expected = float(fresh[0]([0.1, 0.2], [0.3, -0.1], [])[0])
    assert [abs(float(o) - expected) <= 1e-15 * abs(expected) for o in outs] == [True, True]
    assert not list((tmp_path / "nlp").glob("*.lock"))
