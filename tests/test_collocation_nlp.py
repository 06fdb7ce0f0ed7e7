"""The disk cache of the collocation's per-node functions (issue 22): what is read back
evaluates as the freshly built graph (reference: `node_functions` built in the test), and
the key follows the spheres."""

from __future__ import annotations

import numpy as np

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
