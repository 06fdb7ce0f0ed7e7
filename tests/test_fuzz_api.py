"""Fuzz: >= 150 calls of the public API with hostile arguments (wrong dtypes: complex,
strings, booleans, objects; wrong shapes; NaN/inf; absurd sizes; values that overflow
float64). Each must raise a `GeosynError` (never ValueError/TypeError/MemoryError or a
silent NaN) within a time bound. Generated from a seeded catalogue of bad values per
parameter kind."""

from __future__ import annotations

import random
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from fuzzing import assert_geosyn_error, call_api

from conftest import get_metric, get_robot
from geosyn.controllers import ComputedTorque, JointTrajectoryReference, QPController
from geosyn.metrics import exp, log, parallel_transport, path_energy, straight_line
from geosyn.robots import load_robot
from geosyn.sim import Simulation
from geosyn.synergies import GeodesicSynergy, combine
from geosyn.world import Box, Payload, Sphere

Q = np.array([0.2, 0.3])
V = np.array([0.5, -0.4])

#: Bad values by parameter kind; the kind decides what can never be valid.
BAD_VECTOR_2 = [
    np.array([0.2 + 1j, 0.3]),
    np.array([0.2, 0.3], dtype=complex),
    ["a", "b"],
    "0.2, 0.3",
    None,
    {"q": 1},
    np.array([np.nan, 0.0]),
    np.array([np.inf, 0.0]),
    np.array([0.1]),
    np.array([0.1, 0.2, 0.3]),
    np.zeros((2, 2)),
    np.array([object(), object()], dtype=object),
    [[0.1], [0.2]],
    np.array([1e400, 0.0]),
    np.array([True, False]),  # a mask is not a configuration (was read as 0/1)
    [True, 0.3],
]
BAD_POSITIVE = ["1.0", -1.0, 0.0, float("nan"), float("inf"), None, 1 + 1j, [1.0], True]
BAD_COUNT = [1e9, 10**12, 0, -5, "100", 2.5, None, True, np.float64(10.0)]
BAD_GAIN_2 = ["a", 1 + 2j, -1.0, float("nan"), [1.0, 2.0, 3.0], None, {"kp": 1}, ["a", "b"]]
BAD_MASS = [None, "a", -1.0, 1e30, float("inf"), float("nan"), 1j, [1.0]]
BAD_NAME = ["pandda", "", 123, None, b"planar2", "../../etc/passwd", "a" * 5000]


def _metric():
    return get_metric("planar2")


def _robot():
    return get_robot("planar2")


def _ref():
    return JointTrajectoryReference(np.array([0.0, 1.0]), np.stack([Q, Q + 0.1]))


def _geo_samples():
    g = straight_line(Q, Q + 0.5, 1.0, 10)
    return g.t, g.q, g.v


#: Each target: (name, function(**kwargs), the valid keyword arguments, {parameter: bad values}).
TARGETS: list[tuple[str, Callable[..., Any], dict[str, Any], dict[str, list[Any]]]] = [
    ("load_robot", lambda name: load_robot(name), {"name": "planar2"}, {"name": BAD_NAME}),
    (
        "load_robot_options",
        lambda **kw: load_robot("planar2", **kw),
        {},
        {"m1": ["a", -1.0, float("nan"), 1j], "armature": [[0.1] * 5, "x", [-1.0, 0.0]]},
    ),
    (
        "G",
        lambda q: _metric().G(q),
        {"q": Q},
        {"q": BAD_VECTOR_2},
    ),
    (
        "coriolis",
        lambda q, v: _metric().coriolis(q, v),
        {"q": Q, "v": V},
        {"v": [*BAD_VECTOR_2[:8], np.array([1e200, 1e200])]},
    ),
    (
        "geodesic_acceleration",
        lambda q, v: _metric().geodesic_acceleration(q, v),
        {"q": Q, "v": V},
        {"q": BAD_VECTOR_2[:8], "v": [*BAD_VECTOR_2[:8], np.array([1e200, -1e200])]},
    ),
    (
        "exp",
        lambda **kw: exp(_metric(), **kw),
        {"q0": Q, "v0": V, "duration": 1.0, "steps": 20},
        {
            "q0": BAD_VECTOR_2[:10],
            "v0": [*BAD_VECTOR_2[:6], np.array([1e4, 1e4]), np.array([1e6, -1e6])],
            "duration": BAD_POSITIVE,
            "steps": BAD_COUNT,
            "method": ["rk5", "", None, 3],
        },
    ),
    (
        "log",
        lambda **kw: log(_metric(), **kw),
        {"q0": Q, "q1": Q + 0.3},
        {"q0": BAD_VECTOR_2[:8], "q1": BAD_VECTOR_2[:8], "steps": [10**9, 0, "10", 2.5]},
    ),
    (
        "straight_line",
        lambda **kw: straight_line(**kw),
        {"q0": Q, "q1": Q + 1.0, "duration": 1.0, "steps": 10},
        {"q1": BAD_VECTOR_2[:8], "duration": BAD_POSITIVE[:6], "steps": BAD_COUNT},
    ),
    (
        "path_energy",
        lambda t, q: path_energy(_metric(), t, q),
        {"t": _geo_samples()[0], "q": _geo_samples()[1]},
        {
            "t": [
                "abc",
                np.array([0.0, np.nan]),
                np.array([0.0, 0.2, 0.1, *np.linspace(0.3, 1.0, 8)]),
                np.zeros((11, 2)),
            ],
            "q": [np.zeros((11, 3)), np.zeros(11), np.full((11, 2), np.nan), "q"],
        },
    ),
    (
        "parallel_transport",
        lambda **kw: parallel_transport(_metric(), *_geo_samples()[:2], **kw),
        {"v": V},
        {"v": BAD_VECTOR_2[:8], "substeps": BAD_COUNT[1:8]},
    ),
    (
        "GeodesicSynergy",
        lambda **kw: GeodesicSynergy(_metric(), **kw),
        {"q0": Q, "v0": V},
        {"q0": BAD_VECTOR_2[:6], "v0": BAD_VECTOR_2[:6]},
    ),
    (
        "combine",
        lambda weights: combine([GeodesicSynergy(_metric(), Q, e) for e in np.eye(2)], weights),
        {"weights": [0.5, 0.5]},
        {"weights": [[1.0], "ab", [1j, 0.0], [np.nan, 0.0], None, [[1.0, 2.0]]]},
    ),
    (
        "ComputedTorque",
        lambda **kw: ComputedTorque(_robot(), **kw),
        {"kp": 100.0, "kd": 10.0},
        {"kp": BAD_GAIN_2, "kd": BAD_GAIN_2},
    ),
    (
        "QPController",
        lambda **kw: QPController(_robot(), 100.0, 10.0, **kw),
        {"dt": 1e-3},
        {
            "dt": BAD_POSITIVE,
            "max_iter": BAD_COUNT[2:],
            "max_inner_iter": BAD_COUNT[2:],
            "eps": BAD_POSITIVE[:5],
        },
    ),
    (
        "ComputedTorque.compute",
        lambda t, q, v: ComputedTorque(_robot(), 100.0, 10.0, reference=_ref()).compute(t, q, v),
        {"t": 0.1, "q": Q, "v": V},
        {
            "t": ["0.1", None, 1j, float("nan"), [0.1]],
            "q": BAD_VECTOR_2[:8],
            "v": BAD_VECTOR_2[:8],
        },
    ),
    (
        "Payload",
        lambda **kw: Payload("link2", **kw),
        {"mass": 1.0},
        {
            "mass": BAD_MASS,
            "com": [(0.0, 0.0), "abc", (np.nan, 0, 0), (1j, 0, 0)],
            "radius": [-1.0, "r", float("nan")],
            "inertia": [
                ((1.0, 0, 0), (0, 1.0, 0), (0, 0, -1.0)),
                ((1.0, 0, 0), (0, 1.0, 0), (0, 0, 5.0)),
                ((1.0, 2.0, 0), (0, 1.0, 0), (0, 0, 1.0)),
                "I",
            ],
        },
    ),
    (
        "Sphere",
        lambda **kw: Sphere(**kw),
        {"center": (0.0, 0.0, 0.0), "radius": 0.1},
        {"center": [(0.0, 0.0), "c", (np.nan, 0, 0)], "radius": BAD_POSITIVE[:6]},
    ),
    (
        "Box",
        lambda **kw: Box(**kw),
        {"center": (0.0, 0.0, 0.0), "half_extents": (0.1, 0.1, 0.1)},
        {"half_extents": [(0.1, 0.1), (-0.1, 0.1, 0.1), "abc", (np.inf, 0.1, 0.1)]},
    ),
    (
        "Simulation.run",
        lambda **kw: Simulation(_robot(), ComputedTorque(_robot(), 100.0, 10.0)).run(**kw),
        {"q0": Q, "duration": 0.01},
        {
            "q0": BAD_VECTOR_2[:8],
            "v0": [v for v in BAD_VECTOR_2[:9] if v is not None],  # None: at rest (valid)
            "duration": [*BAD_POSITIVE[:6], 1e9, 1e-6],
            "seed": ["s", -1, 1.5],
        },
    ),
    (
        "Simulation",
        lambda **kw: Simulation(_robot(), ComputedTorque(_robot(), 100.0, 10.0), **kw),
        {"control_dt": 1e-3},
        {
            "control_dt": BAD_POSITIVE[:6],
            "substeps": BAD_COUNT[2:7],
            "integrator": ["rk5", None, 3],
            "seed": ["s", -1.5, None],
        },
    ),
]


def _cases() -> list[tuple[str, Callable[..., Any], dict[str, Any]]]:
    rng = random.Random(2026)
    cases = []
    for name, fn, valid, bad in TARGETS:
        for param, values in bad.items():
            for i, value in enumerate(values):
                kwargs = dict(valid)
                kwargs[param] = value
                cases.append((f"{name}-{param}-{i}", fn, kwargs))
    rng.shuffle(cases)  # seeded: any order dependence shows up, reproducibly
    return cases


CASES = _cases()


def test_there_are_at_least_150_cases():
    assert len(CASES) >= 150
    assert len({c[0] for c in CASES}) == len(CASES)


def test_the_valid_calls_succeed():
    for name, fn, valid, _ in TARGETS:
        result = call_api(fn, **valid)
        assert not isinstance(result, BaseException), f"{name}: {result!r}"


@pytest.mark.parametrize("case, fn, kwargs", CASES, ids=[c[0] for c in CASES])
def test_bad_argument_raises_a_geosyn_error(case, fn, kwargs):
    result = call_api(fn, **kwargs)
    assert_geosyn_error(result, case)


def test_simulation_stops_on_a_controller_returning_nan():
    robot = _robot()

    class Broken:
        def reset(self, q, v, t=0.0):
            pass

        def compute(self, t, q, v):
            return np.array([np.nan, 0.0]) if t >= 0.05 - 1e-12 else np.zeros(2)

    res = Simulation(robot, Broken()).run(Q, V * 0, 0.2)
    assert res.status.startswith("diverged: controller returned a non-finite torque")
    assert "t=0.05" in res.status and np.isfinite(res.q).all()
    assert len(res.t) == 50  # the ticks before the bad one are kept
