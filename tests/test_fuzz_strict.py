"""Fuzz (issue 23, second round): configs that mean nothing are refused, failed runs are
NaN, third-party output never precedes geosyn's one line, names are text in the viewer.

Seeded and bounded (each case under `fuzzing.CASE_SECONDS`); every refusal is a
`ConfigError` (never another exception), every accepted case is checked for meaning.
"""

from __future__ import annotations

import functools
import math
import os
import random

import markdown_it
import numpy as np
import pytest
import yaml
from fuzzing import call_api, files_under, time_bound

from geosyn.experiments.cli import main
from geosyn.experiments.cli.exit_codes import EXIT_CODES, NO_RUN_SUCCEEDED, run_exit_code
from geosyn.experiments.config.chatter import captured_stderr, mujoco_warnings
from geosyn.experiments.config.loader import CONFIG_DIR, load_config, read_yaml, validate_config
from geosyn.experiments.errors import ConfigError
from geosyn.experiments.procedures import PROCEDURES
from geosyn.experiments.procedures.base import SECTIONS
from geosyn.experiments.results.summary import clean_summary
from geosyn.experiments.run.run_metrics import Window, standard_metrics
from geosyn.experiments.viewer.text import markdown_text

SRC = "planar2_geodesic_vs_euclidean"
BASE = "ur5_tracking"  # kind tracking: reads every section


def _refused(result: object, *phrases: str) -> str:
    """The message of a `ConfigError` result, which must contain every phrase."""
    assert isinstance(result, ConfigError), f"expected ConfigError, got {result!r}"
    text = str(result)
    assert "\n" not in text
    for phrase in phrases:
        assert phrase in text, text
    return text


# -- duplicate keys ------------------------------------------------------------------------

DUPLICATES = [
    "name: a\nname: b\n",
    "simulation:\n  duration: 1.0\n  duration: 2.0\n",
    "controllers:\n  - {type: qp, kp: 1.0, kp: 2.0}\n",
    "robot: {name: ur5, name: planar2}\n",
    "seed: 1\n'seed': 2\n",  # the same key, quoted once
    "scene:\n  obstacles:\n    - type: box\n      type: sphere\n",
]


@pytest.mark.parametrize("extra", DUPLICATES, ids=range(len(DUPLICATES)))
def test_duplicate_keys_refused_with_their_line(tmp_path, extra):
    path = tmp_path / "dup.yaml"
    path.write_text("kind: tracking\n" + extra)
    _refused(call_api(read_yaml, path), "duplicate key", "line")


def test_merge_keys_may_be_overridden_and_set_values_are_checked(tmp_path):
    path = tmp_path / "m.yaml"
    path.write_text("a: &x {b: 1, c: 2}\nd:\n  <<: *x\n  b: 3\n")
    assert read_yaml(path) == {"a": {"b": 1, "c": 2}, "d": {"b": 3, "c": 2}}
    bad = call_api(load_config, BASE, ["controllers.0={type: qp, kp: 1.0, kp: 2.0}"])
    _refused(bad, "duplicate key")


def test_yaml_1_2_exponents_are_numbers_quoted_numbers_are_not():
    cfg, _ = load_config(BASE, ["simulation.duration=2e0", "controllers.0.kp=9e2"])
    assert cfg.simulation.duration == 2.0 and cfg.controllers[0].kp == 900.0


# -- coercions, booleans, non-finite values -------------------------------------------------

#: (field path, its value in ur5_tracking) of numeric and boolean fields to corrupt.
NUMERIC = [
    "seed",
    "simulation.duration",
    "simulation.control_dt",
    "simulation.substeps",
    "controllers.0.kp",
    "controllers.0.kd",
    "disturbances.0.start",
    "disturbances.0.duration",
    "reference.duration",
    "reference.steps",
    "params.threshold",
]
BOOLEAN = ["simulation.torque_limits", "outputs.plots", "scene.contact", "outputs.csv"]


def _hostile_values(rng: random.Random, boolean: bool) -> list[str]:
    number = f"{rng.uniform(0.001, 5.0):.3f}"
    if boolean:
        return ["1", "0", "'true'", "yes_please", "1.0", number]
    return [
        f"'{number}'",  # a quoted number: text
        "true",
        "false",
        ".inf",
        "-.inf",
        ".nan",
        "'1e3'",
        "[1.0]",
        "{a: 1}",
    ]


def _cases(seed: int = 23) -> list[tuple[str, str]]:
    rng = random.Random(seed)
    out = [(f, v) for f in NUMERIC for v in _hostile_values(rng, False)]
    out += [(f, v) for f in BOOLEAN for v in _hostile_values(rng, True)]
    return out


@pytest.mark.parametrize("field, value", _cases())
def test_coercions_booleans_and_non_finite_values_refused(field, value):
    _refused(call_api(load_config, BASE, [f"{field}={value}"]), field)


def test_the_refusal_names_the_value_and_why():
    text = _refused(call_api(load_config, BASE, ["controllers.0.kp='900'"]), "'900'", "quotes")
    assert "controllers.0.kp" in text
    _refused(call_api(load_config, BASE, ["seed=true"]), "boolean is not a number")
    _refused(call_api(load_config, BASE, ["simulation.substeps=2.0"]), "whole number")


# -- absurd values ---------------------------------------------------------------------------

ABSURD = [
    ("disturbances+={type: sensor_noise, q_std: 1.0e+6}", "3.14"),
    ("disturbances+={type: sensor_noise, v_std: [0, 0, 0, 0, 0, 1.0e+6]}", "1000"),
    ("disturbances+={type: torque_noise, std: 1e6}", "10000"),
    ("disturbances.0.force=[0, 0, 1e300]", "1e+08"),
    ("scene.obstacles.0.center=[1e12, 0, 0]", "1e+08"),
    ("robot.options.gravity=[0, 0, -1e30]", "1e+08"),
]


@pytest.mark.parametrize("override, limit", ABSURD, ids=range(len(ABSURD)))
def test_absurd_values_refused_with_the_limit(override, limit):
    _refused(call_api(load_config, BASE, [override]), limit)


def test_obstacle_inside_the_robot_at_its_start_refused():
    from geosyn.experiments.config.start_clearance import skeleton_points
    from geosyn.robots import load_robot

    cfg, _ = load_config(BASE)
    q = np.asarray(cfg.reference.q_start)
    points = skeleton_points(load_robot("ur5"), q)
    # independent of the skeleton: MuJoCo's own body positions of the UR5 at q_start
    import mujoco

    from geosyn.sim import build_scene

    scene = build_scene(load_robot("ur5"))
    data = mujoco.MjData(scene.model)
    data.qpos[:] = q
    mujoco.mj_kinematics(scene.model, data)
    rng = np.random.default_rng(23)
    for body in rng.choice(np.arange(2, scene.model.nbody), size=4, replace=False):
        c = data.xpos[body] + rng.uniform(-0.01, 0.01, 3)  # a body origin (a joint)
        sphere = f"{{type: sphere, center: [{c[0]}, {c[1]}, {c[2]}], radius: 0.05}}"
        _refused(call_api(load_config, BASE, [f"scene.obstacles.0={sphere}"]), "starts inside")
    for _ in range(4):  # 0.3 m clear of every skeleton point: accepted
        c = rng.uniform(-1.5, 1.5, 3)
        if np.min(np.linalg.norm(points - c, axis=1)) < 0.3:
            continue
        load_config(
            BASE, [f"scene.obstacles.0={{type: sphere, center: {c.tolist()}, radius: 0.05}}"]
        )


# -- sections the kind does not read -----------------------------------------------------------

SET_SECTION = {
    "controllers": "controllers=[{type: computed_torque}]",
    "disturbances": "disturbances=[{type: torque_noise, std: 0.1}]",
    "simulation": "simulation.duration=0.5",
    "reference": "reference={type: log, q_start: [0, 0], goal: [0.3, 0.2], duration: 1.0}",
    "scene": "scene.obstacles=[{type: sphere, center: [2, 2, 2], radius: 0.1}]",
    "synergies": "synergies={type: designed, q0: [0, 0], k: 1}",
}


def test_unused_sections_refused_unless_allowed():
    checked = 0
    rng = random.Random(7)
    kind = PROCEDURES["geodesic_vs_euclidean"]
    unread = [s for s in SECTIONS if s not in (kind.sections or SECTIONS) and s in SET_SECTION]
    assert unread, "the kind reads every section: nothing to check"
    for section in rng.sample(unread, len(unread)):
        with time_bound():
            result = call_api(load_config, SRC, [SET_SECTION[section]])
        _refused(result, section, "does not read", "--allow-unused")
        cfg, _ = load_config(SRC, [SET_SECTION[section]], allow_unused=True)
        assert cfg.kind == "geodesic_vs_euclidean"
        checked += 1
    assert checked >= 2


def test_every_builtin_config_is_strictly_valid():
    for path in sorted(CONFIG_DIR.glob("*.yaml")):
        validate_config(read_yaml(path), path.name)


# -- failed runs --------------------------------------------------------------------------------


def _run(status: str, rng: np.random.Generator, n: int = 50) -> dict[str, object]:
    t = np.arange(n) * 1e-3
    e = rng.normal(0.0, 1e-3, (n, 2))
    return {
        "t": t,
        "tracking_error": e,
        "q_ref": np.zeros((n, 2)),
        "tau_applied": rng.normal(0.0, 1.0, (n, 2)),
        "v": rng.normal(0.0, 1.0, (n, 2)),
        "saturated": rng.random((n, 2)) < 0.3,
        "fallback_used": rng.random(n) < 0.3,
        "contact_force": rng.uniform(0.0, 5.0, n),
        "clearance": rng.uniform(0.01, 0.1, n),
        "wall_time": np.array(1.5),
        "status": np.array(status),
    }


def test_every_metric_of_a_failed_run_is_nan_counts_included():
    rng = np.random.default_rng(23)
    windows = [Window(0, "push", 0.01, 0.02)]
    for status in ("diverged: t=0.05", "controller failed: t=0.01", "stopped: t=0.02"):
        m = standard_metrics(_run(status, rng), 1e-3, windows)
        assert m["ok"] == 0.0 and m["wall_time"] == 1.5
        for name in ("saturations", "fallbacks", "max_contact_force", "rms_error", "effort"):
            assert math.isnan(m[name]), (status, name, m[name])
        assert all(math.isnan(v) for k, v in m.items() if k not in ("ok", "wall_time"))
        summary = clean_summary({f"qp.{k}": v for k, v in m.items()})
        assert summary["failed_runs"] == 1.0 and math.isnan(summary["qp.saturations"])
    ok = standard_metrics(_run("ok", rng), 1e-3, windows)
    assert ok["ok"] == 1.0 and ok["saturations"] > 0 and np.isfinite(ok["rms_error"])


def test_exit_code_says_when_no_run_succeeded():
    assert run_exit_code({"a.ok": 0.0, "b.ok": 0.0, "failed_runs": 2.0}) == NO_RUN_SUCCEEDED
    assert run_exit_code({"a.ok": 1.0, "b.ok": 0.0}) == 0
    assert run_exit_code({"energy": 1.0}) == 0  # no closed-loop run
    assert NO_RUN_SUCCEEDED in EXIT_CODES and 2 in EXIT_CODES


def test_cli_exits_3_when_every_run_failed(tmp_path, monkeypatch, capsys):
    from geosyn.experiments.run import runner

    real = runner.run_experiment

    @functools.wraps(real)  # keeps the signature: the CLI passes the keywords it names
    def every_run_fails(cfg, *args, **kwargs):
        outcome = real(cfg, *args, **kwargs)
        summary = {**outcome.summary, "geodesic.ok": 0.0, "straight.ok": 0.0}
        return outcome._replace(summary=summary)

    monkeypatch.setattr(runner, "run_experiment", every_run_fails)
    monkeypatch.chdir(tmp_path)
    fast = ["--set", "outputs.plots=false", "--set", "params.steps=60", "--no-progress"]
    code = main(["run", SRC, "--out", str(tmp_path / "out"), *fast])
    assert code == NO_RUN_SUCCEEDED and (tmp_path / "out" / "summary.json").is_file()
    assert "no closed-loop run completed" in capsys.readouterr().err


# -- third-party output: one line ---------------------------------------------------------------

_LINK = '<link name="{n}"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>'  # noqa: E501
ROBOT_FILES = {
    "revolute_without_limits.urdf": f'<robot name="r"><link name="a"/>{_LINK.format(n="b")}'
    '<joint name="j" type="revolute"><parent link="a"/><child link="b"/></joint></robot>',
    "unknown_joint_type.urdf": f'<robot name="r"><link name="a"/>{_LINK.format(n="b")}'
    '<joint name="j" type="weird"><parent link="a"/><child link="b"/></joint></robot>',
    "missing_child.urdf": '<robot name="r"><link name="a"/>'
    '<joint name="j" type="fixed"><parent link="a"/><child link="zz"/></joint></robot>',
    "no_robot.urdf": "<notarobot/>",
    "text.urdf": "not xml at all",
    "bad_attribute.xml": '<mujoco><worldbody><body><joint type="hinge"/>'
    '<geom size="x"/></body></worldbody></mujoco>',
    "negative_mass.xml": '<mujoco><worldbody><body><joint type="hinge"/>'
    '<geom size="0.1" mass="-1"/></body></worldbody></mujoco>',
    "nan_in_xml.xml": '<mujoco><worldbody><body><joint type="hinge" axis="0 0 1"/>'
    '<geom size="0.1" pos="nan 0 0"/></body></worldbody></mujoco>',
}


@pytest.mark.parametrize("command", ["run", "explore"])
@pytest.mark.parametrize("name", sorted(ROBOT_FILES))
def test_bad_robot_file_gives_one_stderr_line(tmp_path, monkeypatch, capfd, name, command):
    monkeypatch.chdir(tmp_path)
    (tmp_path / name).write_text(ROBOT_FILES[name])
    (tmp_path / "cfg.yaml").write_text(f"name: t\nkind: tracking\nrobot: {{name: {name}}}\n")
    argv = ["run", "cfg.yaml", "--out", str(tmp_path / "out"), "--no-progress"]
    with time_bound():
        code = main(argv if command == "run" else ["explore", name])
    out, err = capfd.readouterr()
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1, err
    assert lines[0].startswith(f"geosyn {command}: error: ") and "Traceback" not in err
    assert files_under(tmp_path) == sorted(["cfg.yaml", name])  # no MUJOCO_LOG.TXT, no run


def test_captured_stderr_takes_native_output_and_restores_fd2(capfd):
    before = os.fstat(2).st_ino
    with captured_stderr() as got:
        os.write(2, b"Error: from C\n")
    assert got.text == "Error: from C\n" and os.fstat(2).st_ino == before
    assert capfd.readouterr().err == ""


def test_mujoco_warnings_never_write_the_current_directory(tmp_path, monkeypatch):
    import mujoco

    monkeypatch.chdir(tmp_path)
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body><joint/><geom size=".1"/></body></worldbody></mujoco>'
    )
    data = mujoco.MjData(model)
    data.qpos[0] = np.nan
    previous = mujoco.get_mju_user_warning()
    with pytest.warns(UserWarning, match="MuJoCo"), mujoco_warnings() as texts:
        mujoco.mj_step(model, data)
    assert texts and "QPOS" in texts[0]
    assert mujoco.get_mju_user_warning() is previous
    assert files_under(tmp_path) == []


def test_run_keeps_mujoco_and_numpy_chatter_off_the_terminal(tmp_path, monkeypatch, capfd):
    import mujoco

    from geosyn.experiments.run import runner

    real = runner.run_experiment

    @functools.wraps(real)
    def noisy_run(cfg, *args, **kwargs):
        model = mujoco.MjModel.from_xml_string(
            '<mujoco><worldbody><body><joint/><geom size=".1"/></body></worldbody></mujoco>'
        )
        data = mujoco.MjData(model)
        data.qpos[0] = np.nan
        mujoco.mj_step(model, data)  # a MuJoCo warning, as a diverging run gives
        np.log(np.array([-1.0]))  # numpy's RuntimeWarning
        return real(cfg, *args, **kwargs)

    monkeypatch.setattr(runner, "run_experiment", noisy_run)
    monkeypatch.chdir(tmp_path)
    fast = ["--set", "outputs.plots=false", "--set", "params.steps=60", "--no-progress"]
    assert main(["run", SRC, "--out", str(tmp_path / "out"), *fast]) == 0
    err = capfd.readouterr().err
    assert "RuntimeWarning" not in err and "QPOS" not in err
    assert "QPOS" in (tmp_path / "out" / "MUJOCO_LOG.TXT").read_text()
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_only_geosyns_own_warnings_reach_the_terminal():
    import warnings

    from geosyn.experiments.config.chatter import MuJoCoWarning, own_warnings_shown
    from geosyn.robots.errors import RobotWarning

    with warnings.catch_warnings(record=True) as shown:  # what reaches showwarning's output
        previous = warnings.showwarning
        with own_warnings_shown():
            for category in (RobotWarning, RuntimeWarning, MuJoCoWarning, UserWarning):
                warnings.showwarning(f"from {category.__name__}", category, "f.py", 1)
        assert warnings.showwarning is previous
    assert [str(w.message) for w in shown] == ["from RobotWarning"]


# -- the viewer shows names as text -------------------------------------------------------------

HOSTILE_NAMES = [
    "[x](javascript:alert(1)).urdf",
    "<img src=x onerror=alert(1)>.xml",
    "**bold** _em_ `code`.urdf",
    "# heading\n- item.urdf",
    "a|b|c\n|-|-|.urdf",
    "![img](http://127.0.0.1/x.png)",
    "&lt;script&gt;.urdf",
    "<https://example.com>",
    "\\[escaped\\].urdf",
]


def _random_names(seed: int, n: int) -> list[str]:
    rng = random.Random(seed)
    alphabet = "ab.-_*[]()<>!`#|\\&;:/'\"~ "
    return ["".join(rng.choice(alphabet) for _ in range(rng.randrange(1, 30))) for _ in range(n)]


def _texts(tokens: list) -> list[str]:
    out = []
    for tok in tokens:
        assert tok.type not in ("html_inline", "html_block", "link_open", "image", "code_inline")
        assert tok.type not in ("strong_open", "em_open", "heading_open", "bullet_list_open")
        if tok.children:
            out += _texts(tok.children)
        elif tok.type == "text":
            out.append(tok.content)
    return out


@pytest.mark.parametrize("name", HOSTILE_NAMES + _random_names(23, 60))
def test_viewer_renders_a_name_as_its_characters(name):
    md = markdown_it.MarkdownIt("commonmark").enable("table").enable("strikethrough")
    tokens = md.parse(f"**{markdown_text(name)}** (robot)")
    # inside the bold: exactly the name's characters (one line), nothing else parsed
    children = [t for t in tokens if t.type == "inline"][0].children
    inline = [t for t in children if t.type != "text" or t.content]  # markdown-it's empty ones
    assert inline[0].type == "strong_open" and inline[-2].type == "strong_close"
    assert "".join(_texts(inline[1:-2])) == " ".join(name.split())


def test_saved_config_of_an_allowed_run_reloads(tmp_path):
    cfg, _ = load_config(SRC, [SET_SECTION["synergies"]], allow_unused=True)  # not read
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(cfg.model_dump(mode="json")))
    assert load_config(path, allow_unused=True)[0] == cfg
    _refused(call_api(load_config, path), "does not read")
