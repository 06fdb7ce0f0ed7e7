"""The geosyn command line: list, run, report, sweep; bad input exits 2 with one line."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from geosyn.experiments.cli import main
from geosyn.experiments.config.loader import read_yaml, resolve_source

BASE = read_yaml(resolve_source("planar2_geodesic_vs_euclidean"))


def _write(tmp_path: Path, data, name="exp.yaml") -> str:
    path = tmp_path / name
    path.write_text(data if isinstance(data, str) else yaml.safe_dump(data))
    return str(path)


def _with(**changes):
    data = yaml.safe_load(yaml.safe_dump(BASE))
    for key, value in changes.items():
        node = data
        parts = key.split("__")
        for p in parts[:-1]:
            node = node[int(p)] if isinstance(node, list) else node.setdefault(p, {})
        if value is _DELETE:
            del node[parts[-1]]
        elif isinstance(node, list):
            node[int(parts[-1])] = value
        else:
            node[parts[-1]] = value
    return data


_DELETE = object()

# (config document or None for the base config, extra CLI arguments, text the message must contain)
BAD = {
    "unknown_top_key": (_with(colour="red"), [], "colour: unknown key"),
    "unknown_nested_key": (_with(simulation__substep=2), [], "simulation.substep: unknown key"),
    "wrong_type": (
        _with(simulation__duration="long"),
        [],
        "simulation.duration: Input should be a valid number",
    ),
    "unknown_robot": (
        _with(robot__name="pandda"),
        [],
        "robot.name: 'pandda' is not a built-in robot",
    ),
    "unknown_controller": (
        _with(controllers__0__type="lqr"),
        [],
        "controllers.0: unknown type 'lqr'",
    ),
    "negative_dt": (
        _with(simulation__control_dt=-0.001),
        [],
        "simulation.control_dt: Input should be greater than 0",
    ),
    "zero_duration": (
        _with(simulation__duration=0),
        [],
        "simulation.duration: Input should be greater than 0",
    ),
    "gain_dimension": (_with(controllers__0__kp=[1.0, 2.0, 3.0]), [], "controllers.0.kp"),
    "negative_gain": (
        _with(controllers__0__kd=-4.0),
        [],
        "controllers.0.kd: Input should be greater than or equal to 0",
    ),
    "missing_name": (_with(name=_DELETE), [], "name: Field required"),
    "unknown_kind": (_with(kind="dance"), [], "kind: unknown kind 'dance'"),
    "negative_seed": (_with(seed=-2), [], "seed: Input should be greater than or equal to 0"),
    "params_unknown": (_with(params__q2=[0, 0]), [], "params.q2: unknown key"),
    "params_dimension": (
        _with(params__q0=[0.0, 1.0, 2.0]),
        [],
        "params.q0: List should have at most 2 items",
    ),
    "wrong_dof_robot": (
        _with(robot__name="panda"),
        [],
        "robot.name: kind 'geodesic_vs_euclidean' needs a 2-DoF robot",
    ),
    "bad_integrator": (_with(simulation__integrator="RK45"), [], "simulation.integrator"),
    "bad_video_format": (_with(outputs__video_format="avi"), [], "outputs.video_format"),
    "mpc_horizon_zero": (
        _with(controllers__0={"type": "mpc", "horizon": 0}),
        [],
        "controllers.0.horizon",
    ),
    "push_no_duration": (
        _with(
            disturbances=[
                {"type": "push", "body": "link2", "force": [1, 0, 0], "start": 0.1, "duration": 0}
            ]
        ),
        [],
        "disturbances.0.duration: Input should be greater than 0",
    ),
    "unknown_push_body": (
        _with(
            disturbances=[
                {"type": "push", "body": "elbow", "force": [1, 0, 0], "start": 0.1, "duration": 0.1}
            ]
        ),
        [],
        "disturbances.0.body: 'elbow' is not a body, link or frame of 'planar2'",
    ),
    "unknown_payload_frame": (
        _with(scene={"payloads": [{"mass": 1.0, "frame": "hand"}]}),
        [],
        "scene.payloads.0.frame: 'hand' is not a frame of 'planar2'",
    ),
    "unknown_payload_name": (
        _with(
            scene={"payloads": [{"mass": 1.0, "name": "cup"}]},
            disturbances=[{"type": "payload_change", "time": 0.1, "mass": 2.0, "payload": "mug"}],
        ),
        [],
        "disturbances.0.payload: no payload named 'mug'",
    ),
    "payload_index_out_of_range": (
        _with(disturbances=[{"type": "payload_change", "time": 0.1, "mass": 2.0, "payload": 0}]),
        [],
        "disturbances.0.payload: index 0 out of range: 0 payload(s)",
    ),
    "bad_yaml": ("name: x\nrobot: {name: planar2\n", [], "invalid YAML: line"),
    "not_a_mapping": ("- a\n- b\n", [], "must be a YAML mapping"),
    "empty_file": ("", [], "must be a YAML mapping"),
    "bad_set_path": (
        None,
        ["--set", "controllers.5.kp=1"],
        "--set: controllers.5.kp: index 5 out of range",
    ),
    "bad_set_syntax": (
        None,
        ["--set", "simulation.duration"],
        "--set: simulation.duration: expected key.path=value",
    ),
    "set_unknown_key": (
        None,
        ["--set", "simulation.durration=1"],
        "simulation.durration: unknown key",
    ),
    "set_through_value": (
        None,
        ["--set", "robot.name.x=1"],
        "--set: robot.name.x: robot.name is a value",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_config_exits_2_with_one_line(case, tmp_path, capsys, monkeypatch):
    doc, extra, expected = BAD[case]
    monkeypatch.chdir(tmp_path)
    src = _write(tmp_path, BASE if doc is None else doc)
    out = tmp_path / "out"
    code = main(["run", src, "--out", str(out), "--no-progress", *extra])
    captured = capsys.readouterr()
    assert code == 2
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert "Traceback" not in captured.err
    assert lines[0].startswith("geosyn run: error: ConfigError: ")
    assert expected in lines[0], lines[0]
    if doc is not None or case.startswith("bad_set") or case.startswith("set_"):
        assert "exp.yaml" in lines[0] or lines[0].startswith(
            "geosyn run: error: ConfigError: --set"
        )
    assert not out.exists() and not (tmp_path / "runs").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["exp.yaml"]


def test_missing_file_and_unknown_name(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(tmp_path / "nope.yaml")]) == 2
    err = capsys.readouterr().err
    assert "nope.yaml: no such file" in err and len(err.strip().splitlines()) == 1
    assert main(["run", "nonexistent_experiment"]) == 2
    assert "built-ins: arm_synergy_combinations" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_other_commands_bad_input(tmp_path, capsys):
    assert main(["report", str(tmp_path)]) == 2
    assert "has no config.yaml" in capsys.readouterr().err
    assert (
        main(
            [
                "sweep",
                "planar2_geodesic_vs_euclidean",
                "--grid",
                "seed",
                "--out",
                str(tmp_path / "s"),
            ]
        )
        == 2
    )
    assert "ConfigError: --grid: seed: expected key.path=v1,v2" in capsys.readouterr().err
    assert (
        main(
            [
                "sweep",
                "planar2_geodesic_vs_euclidean",
                "--grid",
                "controllers.0.kp=1,-1",
                "--out",
                str(tmp_path / "s"),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert (
        "controllers.0.kp: Input should be greater than or equal to 0" in err
        and "grid point" in err
    )
    assert not (tmp_path / "s").exists()
    assert main(["frobnicate"]) == 2  # argparse usage error


def test_existing_run_directory_needs_force(tmp_path, capsys):
    out = tmp_path / "run"
    out.mkdir()
    args = [
        "run",
        "planar2_geodesic_vs_euclidean",
        "--out",
        str(out),
        "--no-progress",
        "--set",
        "outputs.plots=false",
        "--set",
        "params.steps=100",
    ]
    assert main(args) == 2
    assert "RunDirectoryExists" in capsys.readouterr().err
    assert main([*args, "--force"]) == 0
    stdout = capsys.readouterr().out
    assert "effort" in stdout and "run directory:" in stdout
    assert (out / "summary.json").is_file()


def test_list_shows_experiments_and_robots(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for name in (
        "panda_push_recovery",
        "planar2_geodesic_vs_euclidean",
        "pga_vs_pca",
        "panda",
        "talos_arm",
    ):
        assert name in out


def test_console_script_subprocess(tmp_path):
    script = Path(sys.executable).with_name("geosyn")
    src = _write(tmp_path, _with(controllers__0__kp=-1.0))
    proc = subprocess.run(
        [str(script), "run", src, "--out", str(tmp_path / "o")],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
        env={**os.environ},
    )
    assert proc.returncode == 2
    assert (
        proc.stderr.strip()
        == (
            "geosyn run: error: ConfigError: exp.yaml: controllers.0.kp: "
            "Input should be greater than or equal to 0 (and errors in 1 more field)"
        )
        or "controllers.0.kp: Input should be greater than or equal to 0" in proc.stderr
    )
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "o").exists()


def test_main_restores_the_sigterm_handler(tmp_path, capsys):
    """The CLI routes SIGTERM to SystemExit while a command runs, then puts back the
    handler it found (also after an error)."""
    import signal

    def mine(signum, frame):  # pragma: no cover - never delivered
        pass

    previous = signal.signal(signal.SIGTERM, mine)
    try:
        assert main(["report", str(tmp_path)]) == 2  # an error exit
        assert signal.getsignal(signal.SIGTERM) is mine
        assert main(["robots"]) == 0
        assert signal.getsignal(signal.SIGTERM) is mine
    finally:
        signal.signal(signal.SIGTERM, previous)
    before = signal.getsignal(signal.SIGTERM)
    assert main(["report", str(tmp_path)]) == 2
    assert signal.getsignal(signal.SIGTERM) == before
    capsys.readouterr()


_PROBE = """
import sys
from geosyn.experiments.cli import main
code = main(sys.argv[1:])
heavy = sorted(m for m in ("mujoco", "casadi", "pinocchio", "scipy", "matplotlib")
               if m in sys.modules)
print("HEAVY=" + ",".join(heavy))
sys.exit(code)
"""


@pytest.mark.parametrize(
    "argv, allowed",
    # `list` names the built-in robots: geosyn.robots loads Pinocchio (and MuJoCo, for its
    # MJCF files); it must still not build anything (no CasADi, SciPy, Matplotlib).
    [(["--help"], set()), (["list"], {"pinocchio", "mujoco"})],
)
def test_help_and_list_stay_light(argv, allowed):
    """``geosyn --help`` and ``geosyn list`` answer without importing the heavy libraries
    (checked in a fresh interpreter's ``sys.modules``; the time is measured in
    benchmarks, never asserted)."""
    proc = subprocess.run(
        [sys.executable, "-c", _PROBE, *argv], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    line = [x for x in proc.stdout.splitlines() if x.startswith("HEAVY=")][-1]
    heavy = set(filter(None, line.removeprefix("HEAVY=").split(",")))
    assert heavy <= allowed, f"{argv}: imported {sorted(heavy - allowed)}"


_RUN_IMPORTS = """
import sys
import geosyn.experiments.config.loader, geosyn.experiments.run.runner
import geosyn.experiments.sweep
print("LOADED=" + ",".join(sorted(m for m in sys.modules if m in sys.argv[1:])))
"""
# imported where they are used: a figure (matplotlib), the human study (scipy.signal), a
# spline, an optimiser or a hull (scipy.interpolate / optimize / spatial; scipy.stats under them)
_DEFERRED = (
    "matplotlib",
    "scipy.signal",
    "scipy.stats",
    "scipy.interpolate",
    "scipy.optimize",
    "scipy.spatial",
)


def test_a_run_or_sweep_process_starts_without_the_libraries_it_may_not_use():
    """What `geosyn run` / `sweep` and a sweep's worker import before running (the config
    loader with every procedure, the runner, the sweep) leaves the libraries only some
    runs use to the code that uses them: ~2 s of every process's start, measured 3.3 ->
    1.4 s. Checked in a fresh interpreter's ``sys.modules``."""
    proc = subprocess.run(
        [sys.executable, "-c", _RUN_IMPORTS, *_DEFERRED],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    line = [x for x in proc.stdout.splitlines() if x.startswith("LOADED=")][-1]
    assert line == "LOADED=", line


def test_list_descriptions_match_the_validated_configs(capsys):
    """``list`` reads the raw YAML (no validation, for speed): its first sentences equal
    those of the validated configs."""
    import re

    from geosyn.experiments.config.loader import builtin_names, load_config

    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for name in builtin_names():
        cfg, _ = load_config(name)
        first = re.split(r"(?<=\.)\s", " ".join(cfg.description.split()), maxsplit=1)[0]
        assert f"  {name:<31} {first}\n" in out
