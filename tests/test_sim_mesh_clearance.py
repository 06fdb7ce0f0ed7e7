"""The exact clearance of a simulated run (sim/mesh_clearance.py): the robot file's own
collision meshes against the scene's obstacles, checked against Pinocchio's geometry
model of the same URDF and coal's distances, computed at every logged tick."""

from __future__ import annotations

import math
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest

from geosyn.controllers import ComputedTorque, JointTrajectoryReference
from geosyn.core.errors import InvalidArgument
from geosyn.experiments import load_config, run_experiment
from geosyn.robots import Robot, load_robot
from geosyn.sim import Simulation, blocks
from geosyn.sim.mesh_clearance import MESH_RESOLUTION, checked_ticks
from geosyn.world import Box

Q0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])  # [rad]
Q1 = np.array([0.6, 0.1, 0.0, -1.8, 0.0, 2.0, 0.8])  # [rad]


def pinocchio_distances(robot: Robot, box: Box, Q: np.ndarray) -> np.ndarray:
    """(T,) smallest distance [m] of the URDF's collision geometry to ``box`` at each row
    of ``Q``: Pinocchio's own geometry model of the file (meshes as BVHs), its placements,
    coal's distances; the fingers at 0, where `load_robot("panda")` locks them."""
    path = str(robot.source_file)
    full = pin.buildModelFromUrdf(path)
    share = [str(p) for p in Path(path).parents if p.name == "share"]
    gm = pin.buildGeomFromUrdf(full, path, pin.GeometryType.COLLISION, package_dirs=share)
    n_robot = len(gm.geometryObjects)
    size = 2.0 * np.asarray(box.half_extents)
    placement = pin.SE3(np.asarray(box.rotation), np.asarray(box.center))
    gm.addGeometryObject(pin.GeometryObject("box", 0, placement, coal.Box(*size)))
    for i in range(n_robot):
        gm.addCollisionPair(pin.CollisionPair(i, n_robot))
    gd, data = pin.GeometryData(gm), full.createData()
    idx = [full.idx_qs[full.getJointId(name)] for name in robot.joint_names]
    out = np.empty(len(Q))
    for k, q in enumerate(Q):
        qf = pin.neutral(full)
        qf[idx] = q
        pin.computeDistances(full, data, gm, gd, qf)
        out[k] = min(r.min_distance for r in gd.distanceResults)
    return out


@pytest.fixture(scope="module")
def panda_run():
    robot = load_robot("panda")
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, Q1)
    hand = data.oMf[robot.model.getFrameId("panda_hand")].translation
    box = Box(tuple(hand + [0.0, 0.0, -0.16]), (0.1, 0.1, 0.02))  # below the fingers
    ref = JointTrajectoryReference(np.array([0.0, 1.0]), np.array([Q0, Q1]))
    sim = Simulation(robot, ComputedTorque(robot, 400.0, 40.0), obstacles=[box])
    return robot, box, sim.run(Q0, duration=1.5, reference=ref)


def test_a_run_reports_the_exact_clearance_of_the_robots_meshes(panda_run) -> None:
    robot, box, res = panda_run
    every_tick = pinocchio_distances(robot, box, res.q)
    # over the checked ticks: the same distance as Pinocchio's model of the file (the
    # Panda's collision meshes are convex, so coal on their hulls is exact), to 1e-6 m
    checked = checked_ticks(res.q, MESH_RESOLUTION)
    assert abs(res.mesh_clearance - every_tick[checked].min()) < 1e-6
    # every tick checked or within 0.005 rad of a checked one: the smallest over all ticks
    # is below the reported one by no more than a hand's travel over that step (~5 mm)
    assert every_tick.min() <= res.mesh_clearance + 1e-6
    assert res.mesh_clearance - every_tick.min() < 5e-3
    assert 0.0 < every_tick.min() < 0.05  # the box is near: the check is not vacuous
    assert f"<= {MESH_RESOLUTION:g} rad apart" in res.mesh_clearance_note


def test_a_yaml_run_summarises_and_logs_its_exact_clearance(tmp_path) -> None:
    """A ur5_tracking run (computed torque, the file's box): the summary's
    min_mesh_clearance is the run's, no more than Pinocchio's distance at the checked
    ticks (coal on the meshes' hulls is at most the distance to the meshes), and the run
    log says how it was measured."""
    from geosyn.experiments.run.scene import build_run_scene
    from geosyn.sim import SimResult

    short = ["simulation.duration=0.2", "outputs.plots=false", "outputs.csv=false"]
    cfg, _ = load_config("ur5_tracking", [*short, "controllers=[{type: computed_torque}]"])
    out = run_experiment(cfg, tmp_path / "run", progress=False, quiet=True)
    res = SimResult.load(out.path / "results.npz", "computed_torque")
    assert out.summary["computed_torque.min_mesh_clearance"] == res.mesh_clearance
    (box,) = build_run_scene(cfg).obstacles
    referee = pinocchio_distances(load_robot("ur5"), box, res.q)
    checked = checked_ticks(res.q, MESH_RESOLUTION)
    assert res.mesh_clearance <= referee[checked].min() + 1e-6
    log = (out.path / "run.log").read_text()
    assert (
        f"closed-loop run computed_torque: exact clearance on the robot file's geometry: {len(checked)} ticks"
        in log
    )


def test_what_cannot_be_measured_is_said_not_dropped() -> None:
    """A robot built in code has no file geometry: NaN, and the note says why; with
    mesh_resolution=None the same; without obstacles there is nothing to hit (inf)."""
    robot = load_robot("planar2")
    box = Box((0.5, 0.5, 0.0), (0.05, 0.05, 0.05))
    q0 = np.zeros(robot.nq)
    res = Simulation(robot, ComputedTorque(robot, 100.0, 20.0), obstacles=[box]).run(
        q0, duration=0.01
    )
    assert math.isnan(res.mesh_clearance) and res.mesh_clearance_note.startswith("not measured: ")
    assert "built in code" in res.mesh_clearance_note
    panda = load_robot("panda")
    ct = ComputedTorque(panda, 100.0, 20.0)
    off = Simulation(panda, ct, obstacles=[box], mesh_resolution=None).run(Q0, duration=0.01)
    assert math.isnan(off.mesh_clearance) and "mesh_resolution=None" in off.mesh_clearance_note
    free = Simulation(panda, ct).run(Q0, duration=0.01)
    assert free.mesh_clearance == math.inf and free.mesh_clearance_note == "no obstacles"
    with pytest.raises(InvalidArgument, match="mesh_resolution"):
        Simulation(panda, ct, obstacles=[box], mesh_resolution=-1.0)


@pytest.mark.parametrize("block", [7, blocks.SCAN_BLOCK])
def test_checked_ticks_leave_no_row_farther_than_the_resolution(monkeypatch, block) -> None:
    """Invariant, by brute force: each row is within the resolution (max-norm) of the
    checked row before it; the first and last rows are checked; the same ticks whether
    the log is read in blocks of 7 rows or at once."""
    monkeypatch.setattr(blocks, "SCAN_BLOCK", block)
    rng = np.random.default_rng(3)
    Q = np.cumsum(rng.normal(scale=5e-4, size=(3000, 4)), axis=0)  # [rad]
    for res in (0.005, 0.03):
        ticks = checked_ticks(Q, res)
        assert ticks[0] == 0 and ticks[-1] == len(Q) - 1
        before = ticks[np.searchsorted(ticks, np.arange(len(Q)), side="right") - 1]
        assert np.abs(Q - Q[before]).max() <= res
        assert len(ticks) < len(Q) / 2  # not every row: the resolution thins them
        monkeypatch.setattr(blocks, "SCAN_BLOCK", 10**6)  # the whole log as one block
        np.testing.assert_array_equal(checked_ticks(Q, res), ticks)
        monkeypatch.setattr(blocks, "SCAN_BLOCK", block)
    # a NaN row (a diverged tick) does not stop the checks of the rows after it
    Q_nan = np.cumsum(np.full((50, 2), 1e-3), axis=0)
    Q_nan[20] = np.nan
    ticks = checked_ticks(Q_nan, 0.005)
    assert 21 in ticks and np.all(np.diff(ticks[ticks > 21]) <= 5)
