"""Shared cases of the floating-base tests (tests/test_floating_*.py)."""

from __future__ import annotations

import functools
import warnings
from pathlib import Path

from geosyn.robots import Robot, load_robot

FLOATER = """<mujoco model="floater">
  <option gravity="0 0 0" integrator="RK4" timestep="{dt}"><flag contact="disable"/></option>
  <worldbody>
    <body name="torso" pos="0.1 -0.2 0.8" quat="0.9 0.1 0.3 -0.2">
      <freejoint name="root"/>
      <geom type="box" size="0.2 0.1 0.05" mass="3"/>
      <site name="torso_site" pos="0.1 0 0"/>
      <body name="thigh_l" pos="0.15 0.1 -0.05">
        <joint name="hip_l" axis="0 1 0" armature="0.01"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03" mass="0.8"/>
        <body name="shin_l" pos="0 0 -0.3">
          <joint name="knee_l" axis="0.6 0.8 0" armature="0.005"/>
          <geom type="capsule" fromto="0 0 0 0.05 0 -0.25" size="0.025" mass="0.5"/>
          <site name="foot_l" pos="0.05 0 -0.25"/>
        </body>
      </body>
      <body name="thigh_r" pos="-0.15 -0.1 -0.05">
        <joint name="hip_r" axis="1 0 0"/>
        <geom type="capsule" fromto="0 0 0 0 0.02 -0.3" size="0.03" mass="0.7"/>
      </body>
      <body name="arm" pos="0 0 0.1" euler="0.3 0 0.5">
        <joint name="slide" type="slide" axis="0 0 1"/>
        <geom type="sphere" size="0.05" pos="0.05 0 0" mass="0.4"/>
      </body>
    </body>
  </worldbody>
</mujoco>"""
"""A free-floating body with two legs and a slider: hinges on aligned and unaligned axes,
armature, a rotated root pose; no gravity, no contacts, MuJoCo's RK4."""

CATALOG_FLOATING = ("solo12", "go2", "talos_reduced")


def floater_file(tmp_path: Path, dt: float = 1e-4) -> Path:
    """The `FLOATER` file, with MuJoCo time step ``dt`` [s], written under ``tmp_path``."""
    path = tmp_path / "floater.xml"
    path.write_text(FLOATER.format(dt=dt))
    return path


@functools.cache
def load_quietly(name_or_path: str | Path, **options: object) -> Robot:
    """A robot (loaded once per session), ignoring the default-limit warnings of files
    that state none."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_robot(name_or_path, **options)
