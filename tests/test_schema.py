"""The pydantic experiment schema: unknown keys, types, ranges, DoF checks, unions."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from geosyn.experiments import schema as S
from geosyn.experiments.loader import builtin_names, read_yaml, resolve_source

MINIMAL = {"name": "x", "kind": "push_recovery", "robot": {"name": "planar2"}}


def _cfg(**extra):
    return S.ExperimentConfig.model_validate({**MINIMAL, **extra}, context={"nv": 2})


def test_minimal_config_gets_documented_defaults():
    cfg = _cfg()
    assert cfg.simulation.control_dt == 1e-3
    assert cfg.simulation.integrator == "implicitfast"
    assert cfg.seed == 0 and cfg.controllers == [] and cfg.metric.terms == []


@pytest.mark.parametrize(
    "extra, field",
    [
        ({"unknown": 1}, "unknown"),
        ({"simulation": {"control_dt": -1e-3}}, "control_dt"),
        ({"simulation": {"control_dt": 0.0}}, "control_dt"),
        ({"simulation": {"duration": 1e-4, "control_dt": 1e-3}}, "simulation"),
        ({"simulation": {"integrator": "RK45"}}, "integrator"),
        ({"controllers": [{"type": "computed_torque", "kp": -1.0}]}, "kp"),
        ({"controllers": [{"type": "computed_torque", "kp": [1.0, 2.0, 3.0]}]}, "kp"),
        ({"controllers": [{"type": "lqr"}]}, "controllers"),
        ({"controllers": [{"type": "mpc", "horizon": 0}]}, "horizon"),
        (
            {
                "disturbances": [
                    {"type": "push", "body": "b", "force": [1, 2], "start": 0, "duration": 1}
                ]
            },
            "force",
        ),
        ({"disturbances": [{"type": "latency"}]}, "disturbances"),
        ({"reference": {"type": "log", "q_start": [0.0], "goal": [0.0, 0.0]}}, "q_start"),
        ({"synergies": {"type": "designed", "q0": [0.0, 0.0], "k": 0}}, "k"),
        (
            {"scene": {"obstacles": [{"type": "sphere", "center": [0, 0, 0], "radius": -1}]}},
            "radius",
        ),
        (
            {"scene": {"obstacles": [{"type": "halfspace", "normal": [0, 0, 0], "offset": 0}]}},
            "normal",
        ),
        ({"metric": {"terms": [{"type": "load"}]}}, "terms"),
        ({"seed": -1}, "seed"),
        ({"name": "a b/c"}, "name"),
    ],
)
def test_bad_fields_are_rejected(extra, field):
    with pytest.raises(ValidationError) as info:
        _cfg(**extra)
    locs = [".".join(map(str, e["loc"])) for e in info.value.errors()]
    assert any(field in loc for loc in locs), locs


def test_joint_vectors_are_checked_against_the_robot_dof():
    ref = {"type": "log", "q_start": [0.0, 0.1], "goal": [0.2, 0.3]}
    assert _cfg(reference=ref).reference.goal == [0.2, 0.3]
    with pytest.raises(ValidationError, match="expected 3 values"):
        S.ExperimentConfig.model_validate({**MINIMAL, "reference": ref}, context={"nv": 3})


def test_unknown_robot_lists_the_builtins():
    with pytest.raises(ValidationError, match="available: .*panda"):
        S.RobotConfig.model_validate({"name": "pandda"})


def test_halfspace_normal_is_normalised():
    h = S.HalfSpaceConfig.model_validate({"type": "halfspace", "normal": [0, 0, 2], "offset": 0.1})
    assert h.normal == [0.0, 0.0, 1.0]


def test_controller_labels_are_unique():
    cfg = _cfg(controllers=[{"type": "qp"}, {"type": "qp"}, {"type": "mpc"}])
    assert cfg.controller_labels() == ["qp1", "qp2", "mpc"]


def test_consistency_weights_against_synergies():
    cfg = _cfg(
        synergies={"type": "designed", "q0": [0.0, 0.5], "k": 2},
        reference={"type": "combination", "weights": [1.0, 2.0, 3.0]},
    )
    assert S.consistency_errors(cfg, 2) == [
        ("reference.weights", "expected one weight per synergy (2), got 3")
    ]
    cfg = _cfg(
        synergies={"type": "designed", "q0": [0.0, 0.5], "k": 2},
        reference={"type": "combination", "weights": [1.0, 2.0]},
    )
    assert S.consistency_errors(cfg, 2) == []


def test_every_builtin_config_validates_structurally():
    from geosyn.robots import load_robot

    names = builtin_names()
    assert len(names) == 7
    for name in names:
        data = read_yaml(resolve_source(name))
        nv = load_robot(data["robot"]["name"]).nv
        cfg = S.ExperimentConfig.model_validate(data, context={"nv": nv})
        assert cfg.name == name
