"""Loading configs: built-in names, --set overrides, error messages naming file and field."""

from __future__ import annotations

import pytest
import yaml

from geosyn.experiments.config.loader import (
    apply_override,
    dump_config,
    load_config,
    parse_override,
    validate_config,
)
from geosyn.experiments.errors import ConfigError


def test_builtin_loads_and_params_get_defaults():
    cfg, path = load_config("panda_push_recovery")
    assert path.name == "panda_push_recovery.yaml"
    assert cfg.robot.name == "panda"
    assert cfg.params == {"threshold": 0.01, "window": 1.0}


def test_overrides_change_values_and_are_typed():
    cfg, _ = load_config(
        "panda_push_recovery",
        [
            "simulation.duration=0.5",
            "controllers.1.kp=[1,2,3,4,5,6,7]",
            "outputs.video=true",
            "seed=3",
        ],
    )
    assert cfg.simulation.duration == 0.5
    assert cfg.controllers[1].kp == [1, 2, 3, 4, 5, 6, 7]
    assert cfg.outputs.video is True and cfg.seed == 3


def test_parse_override_yaml_values():
    assert parse_override("a.b=0.25") == ("a.b", 0.25)
    assert parse_override("a=[1, 2]") == ("a", [1, 2])
    assert parse_override("a=text") == ("a", "text")
    assert parse_override("a=[1,") == ("a", "[1,")  # not YAML: kept as text
    for bad in ("novalue", "=3", "a..b=1"):
        with pytest.raises(ConfigError, match="--set"):
            parse_override(bad)


def test_apply_override_paths():
    data = {"a": [{"x": 1}, {"x": 2}], "b": 3}
    apply_override(data, "a.1.x", 5)
    apply_override(data, "c.d", 1)  # missing sections are created
    assert data == {"a": [{"x": 1}, {"x": 5}], "b": 3, "c": {"d": 1}}
    with pytest.raises(ConfigError, match=r"--set: a\.7\.x: index 7 out of range: a has 2 item"):
        apply_override(data, "a.7.x", 1)
    with pytest.raises(ConfigError, match="not an index"):
        apply_override(data, "a.first.x", 1)
    with pytest.raises(ConfigError, match=r"b is a value \(3\), not a section"):
        apply_override(data, "b.c", 1)


@pytest.mark.parametrize(
    "overrides, field, reason",
    [
        (["controllers.1.kp=-1"], "controllers.1.kp", "greater than or equal to 0"),
        (["simulation.control_dt=-0.001"], "simulation.control_dt", "greater than 0"),
        (["simulation.durration=1"], "simulation.durration", "unknown key"),
        (["controllers.2.type=lqr"], "controllers.2", "unknown type 'lqr'"),
        (["robot.name=pandda"], "robot.name", "not a built-in robot"),
        (["synergies.q0=[0, 1]"], "synergies.q0", "expected 7 values"),
        (["kind=dance"], "kind", "unknown kind 'dance'"),
        (["params.treshold=1"], "params.treshold", "unknown key"),
        (["reference.weights=[1.0]"], "reference.weights", "one weight per synergy (2)"),
        (["disturbances.0.payload=4"], "disturbances.0.payload", "out of range"),
    ],
)
def test_errors_name_file_and_field(overrides, field, reason):
    with pytest.raises(ConfigError) as info:
        load_config("panda_push_recovery", overrides)
    err = info.value
    assert err.file == "panda_push_recovery.yaml"
    assert err.field == field
    assert reason in err.reason
    assert str(err).startswith(f"panda_push_recovery.yaml: {field}: ")


def test_file_level_errors(tmp_path):
    with pytest.raises(ConfigError, match="no such file"):
        load_config(tmp_path / "missing.yaml")
    with pytest.raises(ConfigError, match="not a built-in experiment"):
        load_config("no_such_experiment")
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nrobot: [unclosed\n")
    with pytest.raises(ConfigError, match=r"bad.yaml: invalid YAML: line \d+"):
        load_config(bad)
    lst = tmp_path / "list.yaml"
    lst.write_text("- 1\n- 2\n")
    with pytest.raises(ConfigError, match="must be a YAML mapping"):
        load_config(lst)


def test_resolved_config_round_trips():
    cfg, _ = load_config("panda_payload_shaping", ["simulation.duration=0.3"])
    again = validate_config(yaml.safe_load(dump_config(cfg)), "again.yaml")
    assert again == cfg


def test_robot_file_path_is_relative_to_the_config(tmp_path, monkeypatch):
    import os

    from geosyn.robots.files import example_robot_data_dir

    urdf = example_robot_data_dir() / "ur_description" / "urdf" / "ur5_robot.urdf"
    os.symlink(urdf, tmp_path / "arm.urdf")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "e.yaml").write_text(
        yaml.safe_dump(
            {
                "name": "x",
                "kind": "pga_vs_pca",
                "robot": {"name": "../arm.urdf"},
                "params": {"q0": [0.0, -1.0, 1.0, 0.0, 0.0, 0.0], "k_max": 2},
            }
        )
    )
    monkeypatch.chdir("/")
    cfg, _ = load_config(tmp_path / "sub" / "e.yaml")
    assert cfg.robot.name == str(urdf.resolve())
    with pytest.raises(ConfigError, match=r"params\.q0: expected 6 values"):
        load_config(tmp_path / "sub" / "e.yaml", ["params.q0=[0, 0]"])


@pytest.mark.parametrize("loader", ["SafeLoader", "CSafeLoader"])
@pytest.mark.parametrize("kind", ["flow", "map", "block"])
@pytest.mark.parametrize("depth", [33, 999, 1000, 5000])
def test_nesting_limit_is_geosyn_s_whatever_parser_stops_first(
    tmp_path, monkeypatch, loader, kind, depth
):
    """Too deep a config gives geosyn's own message (the limit and how to fix it) whether
    the data reaches geosyn's check, libyaml stops at its own depth limit (PyYAML >= 6.0.4
    at 1000 levels) or Python's recursion limit stops the pure-Python parser."""
    import yaml

    from geosyn.experiments.config import loader as loader_mod
    from geosyn.experiments.config.resource_limits import MAX_DEPTH
    from geosyn.experiments.errors import ConfigError

    if not hasattr(yaml, loader):
        pytest.skip(f"PyYAML built without {loader}")
    monkeypatch.setattr(loader_mod, "SAFE_LOADER", getattr(yaml, loader))
    if kind == "flow":
        text = "x: " + "[" * depth + "]" * depth + "\n"
    elif kind == "map":
        text = "x: " + "{a: " * depth + "1" + "}" * depth + "\n"
    else:
        depth = min(depth, 400)  # indented lines grow quadratically
        text = "x:\n" + "".join("  " * (i + 1) + "a:\n" for i in range(depth))
    path = tmp_path / "deep.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        loader_mod.read_yaml(path)
    assert f"nested deeper than {MAX_DEPTH} levels" in str(info.value)
    assert "flatten" in str(info.value)
    with pytest.raises(ConfigError) as info:
        loader_mod.parse_override("params.x=" + text[3:].strip())
    assert f"nested deeper than {MAX_DEPTH} levels" in str(info.value)
