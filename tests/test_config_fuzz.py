"""Malformed experiment files: each exits 2 with one clear line and leaves nothing."""

from __future__ import annotations

import copy
import random

import pytest
import yaml

from geosyn.experiments.cli import main

BASE = {
    "name": "fuzz",
    "kind": "tracking",
    "robot": {"name": "planar2"},
    "scene": {"obstacles": [{"type": "sphere", "center": [0.5, 0.5, 0.0], "radius": 0.1}]},
    "reference": {"type": "log", "q_start": [0.2, 0.3], "goal": [0.8, 0.9], "duration": 0.5},
    "controllers": [{"type": "qp", "kp": 400.0, "kd": 40.0}],
    "disturbances": [
        {"type": "push", "body": "link2", "force": [0.0, 5.0, 0.0], "start": 0.1, "duration": 0.05}
    ],
    "simulation": {"duration": 0.3, "control_dt": 0.002},
    "params": {"threshold": 0.01},
}


def _with(path: str, value=None, delete=False):
    data = copy.deepcopy(BASE)
    *head, last = path.split(".")
    node = data
    for part in head:
        node = node[int(part)] if isinstance(node, list) else node[part]
    if delete:
        del node[last]
    elif isinstance(node, list):
        node[int(last)] = value
    else:
        node[last] = value
    return yaml.safe_dump(data)


#: (file text, a field path or phrase the message must name)
HANDMADE = [
    ("name: x\nrobot: [unclosed\n", "invalid YAML"),
    ("- 1\n- 2\n", "must be a YAML mapping"),
    ("", "must be a YAML mapping"),
    ("just a string\n", "must be a YAML mapping"),
    (_with("robot", delete=True), "robot"),
    (_with("robot.name", "pandda"), "robot.name"),
    (_with("kind", "trackin"), "did you mean 'tracking'"),
    (_with("kind", 3), "kind"),
    (_with("name", "has space"), "name"),
    (_with("seed", -1), "seed"),
    (_with("reference.type", "lgo"), "did you mean 'log'"),
    (_with("reference.goal", [1.0]), "reference.goal"),
    (_with("reference.q_start", "zero"), "reference.q_start"),
    (_with("reference.duration", 0.0), "reference.duration"),
    (_with("reference", delete=True), "reference"),
    (_with("controllers", []), "controllers"),
    (_with("controllers.0.type", "pid"), "controllers.0"),
    (_with("controllers.0.kpp", 1.0), "did you mean 'kp'"),
    (_with("controllers.0.kd", -1.0), "controllers.0.kd"),
    (_with("disturbances.0.body", "no_such_link"), "disturbances.0.body"),
    (_with("disturbances.0.force", [1.0, 2.0]), "disturbances.0.force"),
    (_with("disturbances.0.duration", -0.1), "disturbances.0.duration"),
    (_with("scene.obstacles.0.radius", 0.0), "scene.obstacles.0.radius"),
    (_with("scene.obstacles.0.type", "cube"), "scene.obstacles.0"),
    (_with("simulation.durration", 1.0), "did you mean 'duration'"),
    (_with("simulation.control_dt", 0.0), "simulation.control_dt"),
    (_with("simulation.integrator", "rk5"), "simulation.integrator"),
    (_with("params.treshold", 1.0), "did you mean 'threshold'"),
    (_with("params.threshold", "high"), "params.threshold"),
    (_with("outputs", {"video_format": "avi"}), "outputs.video_format"),
    (_with("metric", {"terms": [{"type": "load"}]}), "metric.terms.0"),
]

#: Mutations that always make a config invalid: (name, function(data, rng) -> data).
SECTIONS = ["reference", "controllers.0", "disturbances.0", "simulation", "params"]


def _mutate(rng: random.Random) -> str:
    data = copy.deepcopy(BASE)
    where = rng.choice(SECTIONS)
    node = data
    for part in where.split("."):
        node = node[int(part)] if isinstance(node, list) else node[part]
    numeric = [k for k, v in node.items() if isinstance(v, float) and k != "type"]
    kind = rng.choice(["unknown_key", "string_number", "negative", "list_for_number"])
    if kind == "unknown_key" or not numeric:
        node[rng.choice(["foo", "kp_", "durations", "bdy", "x"])] = 1
    elif kind == "string_number":
        node[rng.choice(numeric)] = rng.choice(["fast", "", "1.0.0"])
    elif kind == "negative":
        key = rng.choice(numeric)
        node[key] = -abs(node[key]) - 1.0
        if where == "disturbances.0" and key == "force":  # a force may be negative
            node["duration"] = -1.0
    else:
        node[rng.choice(numeric)] = {"nested": [1, 2]}
    return yaml.safe_dump(data)


RANDOM = [_mutate(random.Random(seed)) for seed in range(16)]


def test_the_base_config_is_valid():
    from geosyn.experiments.config.loader import validate_config

    validate_config(BASE)


@pytest.mark.parametrize(
    "text, phrase",
    HANDMADE + [(t, "") for t in RANDOM],
    ids=[f"hand{i}" for i in range(len(HANDMADE))] + [f"rand{i}" for i in range(len(RANDOM))],
)
def test_malformed_file_exits_2_with_one_clear_line_and_leaves_nothing(
    tmp_path, capsys, text, phrase
):
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(text)
    out = tmp_path / "runs" / "r"
    code = main(["run", str(cfg), "--out", str(out), "--no-progress"])
    captured = capsys.readouterr()
    assert code == 2, captured
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("geosyn run: error: ConfigError: bad.yaml: ")
    assert "Traceback" not in captured.err and captured.out == ""
    assert phrase in lines[0]
    # nothing left behind: only the config file itself
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["bad.yaml"]
