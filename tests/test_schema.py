"""The pydantic experiment schema: unknown keys, types, ranges, DoF checks, unions."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from geosyn.experiments import schema as S
from geosyn.experiments.config.loader import builtin_names, read_yaml, resolve_source

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
    assert len(names) >= 8 and "ur5_tracking" in names  # the paper's seven and more
    for name in names:
        data = read_yaml(resolve_source(name))
        nv = load_robot(data["robot"]["name"]).nv
        cfg = S.ExperimentConfig.model_validate(data, context={"nv": nv})
        assert cfg.name == name


# -- schema help: `geosyn schema`, `geosyn init`, suggestions, every error listed ----------


def test_every_field_has_a_meaning_and_the_documented_units():
    from geosyn.experiments.procedures import PROCEDURES
    from geosyn.experiments.schema.describe import undocumented, walk

    declared = [p.Params for p in PROCEDURES.values() if p.sections is not None]
    assert undocumented([S.ExperimentConfig, *declared]) == []
    docs = {d.path: d for d in walk(S.ExperimentConfig)}
    # units and defaults come from the constructors' docstrings and signatures
    kp = docs["controllers[][type=qp].kp"]
    assert (kp.unit, kp.default) == ("1/s^2", "400.0")
    assert docs["disturbances[][type=push].force"].unit == "N"
    assert docs["simulation.control_dt"].unit == "s"
    assert docs["simulation.control_dt"].default == str(S.SimulationConfig().control_dt)
    assert docs["reference[type=log].goal"].default == "required"
    assert "> 0" in docs["simulation.duration"].type


def test_schema_command_prints_sections_and_suggests_names(capsys):
    from geosyn.experiments.cli import main

    assert main(["schema"]) == 0
    top = capsys.readouterr().out
    assert "controllers:" in top and "simulation:" in top
    assert main(["schema", "push"]) == 0
    push = capsys.readouterr().out
    assert "disturbances[][type=push].force: list[float]" in push and "[N]" in push
    assert main(["schema", "tracking"]) == 0
    assert "params[kind=tracking].threshold: float > 0.0 = 0.01 [rad]" in capsys.readouterr().out
    assert main(["schema", "pus"]) == 2
    assert "did you mean 'push'" in capsys.readouterr().err


def test_kinds_table_is_the_documented_one():
    from pathlib import Path

    from geosyn.experiments.cli.schema_commands import kinds_table

    doc = (Path(__file__).resolve().parent.parent / "docs" / "experiments.md").read_text()
    for line in kinds_table().splitlines():
        if "?" not in line:  # the declared kinds
            assert line in doc


def test_init_writes_a_template_that_validates_and_runs(tmp_path, monkeypatch, capsys):
    from geosyn.experiments import load_config, run_experiment
    from geosyn.experiments.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["init", "mine", "--robot", "ur5"]) == 0
    text = (tmp_path / "mine.yaml").read_text()
    assert text.count("#") > 15  # commented
    assert main(["init", "mine"]) == 2  # never overwritten
    assert "exists" in capsys.readouterr().err
    assert main(["init", "mine2", "--robot", "ur55"]) == 2
    assert "did you mean 'ur5'" in capsys.readouterr().err
    cfg, _ = load_config(tmp_path / "mine.yaml", ["simulation.duration=0.2", "outputs.plots=false"])
    assert cfg.kind == "tracking" and cfg.robot.name == "ur5" and cfg.reference.rest_to_rest
    out = run_experiment(cfg, tmp_path / "run", progress=False, quiet=True)
    assert out.summary["qp.ok"] == out.summary["computed_torque.ok"] == 1.0
    assert out.summary["qp.rms_error"] < 1e-3  # a feasible, rest-to-rest start


def test_unknown_keys_suggest_the_closest_valid_ones():
    from geosyn.experiments import ConfigError, load_config

    with pytest.raises(ConfigError) as info:
        load_config("ur5_tracking", ["controllers.0.kpp=1"])
    assert info.value.field == "controllers.0.kpp"
    assert "did you mean 'kp'?" in info.value.reason
    assert "valid keys here:" in info.value.reason and "braking_acceleration" in info.value.reason
    with pytest.raises(ConfigError, match="did you mean 'duration'"):
        load_config("ur5_tracking", ["simulation.durration=1"])
    with pytest.raises(ConfigError, match="did you mean 'tracking'"):
        load_config("ur5_tracking", ["kind=trackng"])
    with pytest.raises(ConfigError, match="did you mean 'box'"):
        load_config("ur5_tracking", ["scene.obstacles.0.type=boxx"])


def test_all_errors_of_a_file_are_listed(tmp_path):
    import yaml

    from geosyn.experiments import ConfigError, load_config

    bad = tmp_path / "bad.yaml"
    data = read_yaml(resolve_source("ur5_tracking"))
    data["controllers"][0]["kd"] = -1
    data["simulation"]["control_dt"] = 0
    data["params"] = {"treshold": 1}
    data["reference"]["goal"] = [0.0]
    bad.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError) as info:
        load_config(bad)
    text = str(info.value)
    for field in ("controllers.0.kd", "simulation.control_dt", "params.treshold", "reference.goal"):
        assert f"{field}: " in text, field
    assert "(4 problems)" in text and "more field" not in text
    assert "\n" not in text


def test_set_appends_to_lists():
    from geosyn.experiments import ConfigError, load_config
    from geosyn.experiments.config.loader import apply_override, parse_override

    cfg, _ = load_config("ur5_tracking", ["controllers+={type: computed_torque, label: ct}"])
    assert [c.type for c in cfg.controllers] == ["qp", "computed_torque"]
    assert cfg.controller_labels() == ["qp", "ct"]
    data: dict = {}
    apply_override(data, *parse_override("scene.obstacles+={type: sphere}"))
    apply_override(data, *parse_override("scene.obstacles+=[1]"))
    assert data == {"scene": {"obstacles": [{"type": "sphere"}, [1]]}}
    with pytest.raises(ConfigError, match="not a list"):
        load_config("ur5_tracking", ["simulation+=1"])
