"""YAML ``robot.options`` carries every loader option, ``geosyn init --robot PATH`` takes a
file, and the command line shows geosyn's warnings once, on one line (issue 21)."""

from __future__ import annotations

import inspect
import warnings
from pathlib import Path

import numpy as np
import yaml

from geosyn.experiments import load_config
from geosyn.experiments.cli import main
from geosyn.experiments.cli.schema_commands import schema_text
from geosyn.experiments.cli.warning_format import geosyn_warnings_once
from geosyn.experiments.run.scene import build_robot
from geosyn.experiments.schema.scene import RobotOptions
from geosyn.robots.errors import RobotWarning
from geosyn.robots.files import load_file
from geosyn.robots.from_model import robot_from_model

FIXTURES = Path(__file__).parent / "fixtures"
#: robot_from_model's parameters that the file loader fills itself (not user options).
INTERNAL = {
    "model", "name", "capsules", "file_tau_max", "limit_source", "actuators", "base",
    "source_file", "couplings",
}  # fmt: skip


def test_every_loader_option_is_a_yaml_option_explained_by_the_schema() -> None:
    user = set(inspect.signature(robot_from_model).parameters) - INTERNAL
    user |= {"fixed_base", "floating_base", "inertia_check"}  # load_file's own (its doc)
    assert all(f"``{o}``" in (load_file.__doc__ or "") for o in ("fixed_base", "inertia_check"))
    assert user <= set(RobotOptions.model_fields), user - set(RobotOptions.model_fields)
    text = schema_text("robot")
    for option in user:
        line = next(li for li in text.splitlines() if li.startswith(f"robot.options.{option}:"))
        explanation = text.splitlines()[text.splitlines().index(line) + 1].strip()
        assert len(explanation) > 15, (option, explanation)


def _config(tmp_path: Path, options: dict) -> Path:
    cfg = {
        "name": "opts",
        "kind": "tracking",
        "robot": {"name": str(FIXTURES / "scene_arm.xml"), "options": options},
        "reference": {"type": "log", "q_start": [0.0, 0.2], "goal": [0.3, 0.4], "duration": 0.3},
        "controllers": [{"type": "computed_torque", "kp": 100.0, "kd": 20.0}],
        "simulation": {"duration": 0.3},
        "outputs": {"plots": False},
    }
    path = tmp_path / "opts.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def test_yaml_loader_options_reach_the_robot(tmp_path: Path) -> None:
    options = {
        "default_v_max": 2.0,
        "default_tau_max": 30.0,
        "keep_joints": ["j1", "j2"],
        "lock_q": {"j3": 0.3},
        "damping": {"j1": 0.5},
        "frictionloss": {},
        "capsule_radius": 0.05,
    }
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RobotWarning)
        cfg, _ = load_config(str(_config(tmp_path, options)))
        robot = build_robot(cfg)
    assert robot.joint_names == ("j1", "j2") or list(robot.joint_names) == ["j1", "j2"]
    np.testing.assert_allclose(robot.v_max, [2.0, 2.0])
    np.testing.assert_allclose(robot.tau_max, [30.0, 30.0])
    np.testing.assert_allclose(robot.damping, [0.5, 0.0])
    # j3 locked at 0.3 rad: the tip of the two-joint robot at q = 0 is where the file's is.
    frame = robot.model.getFrameId("tip")
    import pinocchio as pin

    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, np.zeros(2))
    tip_z = 0.3 + 0.2 - 0.3 * np.sin(0.3)  # l1 height + l2 offset, l3 pitched by j3
    np.testing.assert_allclose(data.oMf[frame].translation, [0.4 + 0.3 * np.cos(0.3), 0, tip_z])


def test_init_accepts_a_robot_file_path(tmp_path: Path, capsys) -> None:
    out = tmp_path / "cpl.yaml"
    robot = FIXTURES / "coupled.xml"
    assert main(["init", "cpl", "--robot", str(robot), "--out", str(out)]) == 0
    cfg, _ = load_config(str(out))
    assert Path(cfg.robot.name) == robot.resolve()
    q0, q1 = np.array(cfg.reference.q_start), np.array(cfg.reference.goal)
    for q in (q0, q1):  # on the file's couplings (j3 = 0.1 + 0.5 j2, j4 = 0.8 j3)
        assert abs(q[2] - 0.1 - 0.5 * q[1]) < 1e-12 and abs(q[3] - 0.8 * q[2]) < 1e-12
    assert main(["init", "x", "--robot", str(tmp_path / "none.xml")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_geosyn_warnings_print_once_without_a_source_line(capsys) -> None:
    others: list[str] = []
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = lambda message, category, *rest: others.append(str(message))
        before = warnings.showwarning
        with geosyn_warnings_once():
            for _ in range(3):
                warnings.warn("robot 'x': no torque limit", RobotWarning, stacklevel=1)
            warnings.warn("someone else's", UserWarning, stacklevel=1)
        assert warnings.showwarning is before  # restored
    err = capsys.readouterr().err
    assert err == "warning: RobotWarning: robot 'x': no torque limit\n"  # once, no source
    assert others == ["someone else's"]  # other warnings go to the previous handler


def test_geosyn_run_prints_each_robot_warning_once(tmp_path: Path, capsys) -> None:
    """The robot is loaded twice (config check, then the run): each warning shows once."""
    path = _config(tmp_path, {"keep_joints": ["j1", "j2"]})
    assert main(["run", str(path), "--out", str(tmp_path / "run"), "--no-progress"]) == 0
    err = capsys.readouterr().err
    lines = [li for li in err.splitlines() if li.startswith("warning: RobotWarning:")]
    assert lines and len(lines) == len(set(lines)), err
    assert "no velocity limit" in err and "loading.py" not in err
