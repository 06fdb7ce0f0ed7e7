"""Floating-base robots in YAML runs (geosyn/experiments/run/floating.py): the built-in
experiments talos_stance_push and go2_body_shift stand under a 50 N push on the base,
with the base free in MuJoCo.

References: the feet's slip and the tracking error are recomputed from the logged
configurations with Pinocchio's own kinematics and group difference (independent of the
loop's bookkeeping); the acceptance bounds of issue 26 (slip <= 1 mm, no fall).
"""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest
from PIL import Image

from geosyn.experiments.config.loader import load_config
from geosyn.experiments.errors import ConfigError
from geosyn.experiments.run.runner import run_experiment


def _feet_slip(robot, q: np.ndarray, feet: list[str]) -> float:  # type: ignore[no-untyped-def]
    data = robot.model.createData()
    ids = [robot.frame_id(f) for f in feet]

    def positions(qk: np.ndarray) -> np.ndarray:
        pin.framesForwardKinematics(robot.model, data, qk)
        return np.array([data.oMf[i].translation for i in ids])

    p0 = positions(q[0])
    return max(float(np.abs(positions(qk)[:, :2] - p0[:, :2]).max()) for qk in q[1:])


@pytest.mark.parametrize(
    ("name", "duration", "low"),
    [("talos_stance_push", 1.0, 0.9), ("go2_body_shift", 1.2, 0.25)],
)
def test_built_in_floating_experiment_stands_under_a_50_newton_push(
    tmp_path, name: str, duration: float, low: float
) -> None:
    overrides = [f"simulation.duration={duration}", "outputs.fps=25", "outputs.width=160"]
    cfg, _ = load_config(name, [*overrides, "outputs.height=120"])  # the push is 0.8 - 1.0 s
    out = run_experiment(cfg, tmp_path / name, video=True, progress=False, quiet=True)
    s = out.summary
    # measured: talos slip 0.21 mm, sink 0.70 mm, base >= 0.95 m; go2 0.63 mm, 1.3 mm, 0.27 m
    assert s["whole_body.ok"] == 1.0 and s["whole_body.fallbacks"] == 0.0
    assert s["whole_body.feet_slip"] <= 1e-3 and s["whole_body.feet_sink"] < 2e-3
    assert s["whole_body.min_base_height"] > low
    with np.load(out.path / "results.npz") as f:
        q, q_ref = f["whole_body__q"], f["whole_body__q_ref"]
        error = f["whole_body__tracking_error"]
    robot = cfg_robot(cfg)
    assert q.shape == (round(duration / 1e-3), robot.nq)
    # the feet slip of the last logged state onwards is within one tick of the summary's
    assert _feet_slip(robot, q, cfg.stance.frames) <= s["whole_body.feet_slip"] + 1e-12
    diff = np.array([pin.difference(robot.model, a, b) for a, b in zip(q, q_ref, strict=True)])
    np.testing.assert_allclose(error, diff, atol=1e-12)
    assert s["whole_body.rms_error"] == pytest.approx(np.sqrt(np.mean(diff**2)), rel=1e-12)
    assert 0.0 < s["whole_body.rms_error"] < 0.06  # measured 0.043 (talos), 0.0077 (go2)
    video = json.loads((out.path / "run.json").read_text())["video"]
    assert video["error"] is None and video["files"] == ["video_whole_body.gif"]
    with Image.open(out.path / "video_whole_body.gif") as gif:  # 25 fps over the run
        assert gif.n_frames == video["frames"] == int(25 * (duration - 1e-3)) + 1


def cfg_robot(cfg):  # type: ignore[no-untyped-def]
    from geosyn.experiments.run.scene import build_robot

    return build_robot(cfg)


def _write(tmp_path, text: str):  # type: ignore[no-untyped-def]
    path = tmp_path / "bad.yaml"
    path.write_text(text, encoding="utf-8")
    return path


GO2 = """
name: bad
kind: tracking
robot: {name: go2}
stance: {frames: [FL_foot, FR_foot, RL_foot, RR_foot]}
reference: {type: stance_synergy, direction: {base: [0, 0.05, -0.04, 0.1, 0, 0]}, duration: 1.0}
controllers: [{type: whole_body}]
simulation: {duration: 0.01}
"""


@pytest.mark.parametrize(
    ("old", "new", "field", "words"),
    [
        ("{type: whole_body}", "{type: computed_torque}", "controllers.0", "needs a fixed-base"),
        (
            "controllers:",
            "disturbances: [{type: push, body: FL_calf, force: [0, 50, 0],"
            " start: 0.1, duration: 0.1}]\ncontrollers:",
            "disturbances.0.body",
            "acts on the base",
        ),
        (
            "stance: {frames: [FL_foot, FR_foot, RL_foot, RR_foot]}\n",
            "",
            "stance",
            "needs a stance",
        ),
        ("robot: {name: go2}", "robot: {name: panda}", "stance", "has a fixed base"),
    ],
)
def test_a_floating_config_that_cannot_stand_is_refused_naming_the_field(
    tmp_path, old: str, new: str, field: str, words: str
) -> None:
    assert old in GO2
    with pytest.raises(ConfigError) as err:
        load_config(_write(tmp_path, GO2.replace(old, new)))
    assert err.value.field == field and words in err.value.reason


def test_a_stance_frame_or_joint_that_does_not_exist_is_one_clear_error(tmp_path) -> None:
    with pytest.raises(ConfigError) as err:
        load_config(_write(tmp_path, GO2.replace("FL_foot", "FL_toe")))
    assert err.value.field == "stance.frames.0"
    assert "'FL_toe' is not a frame of 'go2'" in err.value.reason and "FL_foot" in err.value.reason
    text = GO2.replace("0.1, 0, 0]}", "0.1, 0, 0], joints: {FL_knee: 0.1}}")
    with pytest.raises(ConfigError) as err:
        load_config(_write(tmp_path, text))
    assert err.value.field == "reference.direction.joints" and "FL_calf_joint" in err.value.reason
