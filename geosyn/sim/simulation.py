"""Closed-loop torque control of a `Robot` simulated in MuJoCo, under disturbances.

One control tick of period ``control_dt`` (zero-order hold over ``substeps`` physics steps
of ``control_dt / substeps``):

1. position- and velocity-dependent quantities of the true state ``(q_k, v_k)`` at
   ``t_k = k control_dt`` are computed (``mj_step1``; ``mj_forward`` with RK4);
2. the measurement hooks of the disturbances give the controller's ``(q, v)``
   (sensor noise, latency);
3. the controller returns ``tau`` (nv,) [N m] from ``compute(t_k, q, v)``;
4. torque hooks (torque noise) modify it, the result is clipped to the torque limits
   (MuJoCo's ctrlrange, recorded as saturation) and sent to the motors;
5. tick hooks act on the data (pushes, wrenches); model changes (payload masses) are
   made by the disturbances' ``before_tick`` hooks before step 1;
6. the physics advances by ``substeps`` steps (``mj_step2`` then ``mj_step``; RK4: ``mj_step``);
7. the new state is checked (`geosyn.sim.divergence`): a diverged state stops the run
   with a status ``"diverged: ..."``; the ticks run so far are kept.

The controller never sees MuJoCo: it is any object with ``reset(q, v, t)``,
``compute(t, q, v) -> tau``, ``set_reference(ref)`` when a reference is passed to `run`,
and optionally a ``diagnostics`` attribute (``fallback_used``, ``solver_status``,
``iterations``) that is logged per tick.
"""

from __future__ import annotations

import copy
import math
import os
import time
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

from geosyn.core.errors import GeosynError, InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_choice, check_int, check_positive, check_vector
from geosyn.robots.robot import Robot
from geosyn.sim.controller_api import (
    ControllerLike,
    ReferenceLike,
    check_parts,
    controller_notes,
)
from geosyn.sim.disturbances import Disturbance, overrides
from geosyn.sim.divergence import SPEED_FACTOR, DivergenceCheck
from geosyn.sim.file_scene import build_file_scene
from geosyn.sim.log import SimResult
from geosyn.sim.log_spool import LogWriter, open_log
from geosyn.sim.mesh_clearance import MESH_RESOLUTION, MeshClearance, RunClearance
from geosyn.sim.obstacles import obstacle_contact_force
from geosyn.sim.scene import Scene, build_scene, torque_range
from geosyn.world import Payload


class Simulation:
    """Torque control of a robot in MuJoCo, with payloads, obstacles and disturbances.

    Build once (compiles the MuJoCo model, binds the disturbances), then `run` any number
    of times; each run starts from a reset model and reseeded disturbances, so two runs
    with the same arguments give identical logs.

    Args:
        robot: the robot; the MuJoCo model is built from it (`geosyn.sim.build_scene`).
        controller: the controller (see the module doc).
        control_dt: control period [s], > 0.
        substeps: physics steps per control tick, >= 1 (physics time step is
            ``control_dt / substeps``).
        integrator: MuJoCo integrator: implicitfast (default), implicit, Euler or RK4.
        payloads: payload bodies welded to links (`geosyn.sim.Payload`).
        obstacles: Sphere/Box/Capsule/HalfSpace-like obstacles (see `geosyn.sim.scene`).
        disturbances: disturbances, applied in order (deep-copied here).
        gravity: (3,) gravity [m/s^2]; defaults to ``robot.gravity``.
        seed: seed of the disturbances' random generators (one independent stream each).
        contact: obstacles collide with the robot (default: visual only, clearance logged).
        torque_limits: clip torques to the robot's limits (MuJoCo ctrlrange). With False
            the command is applied as is and no saturation is recorded.
        position_limits: MuJoCo enforces the finite joint position limits.
        plant: ``model`` (default) simulates geosyn's rebuilt model of the robot
            (`geosyn.sim.build_scene`); ``file`` simulates the robot's original MJCF file
            (`geosyn.sim.file_scene`: its meshes, contacts and joint properties, its
            actuators disabled, geosyn's torques applied as joint forces ``qfrc_applied``
            and clipped to ``robot.tau_max``), with the payloads, obstacles and contact
            added to the file as to the model.
        mesh_resolution: joint-space step [rad] at which each run's motion is checked
            on the robot file's collision geometry against the obstacles after the run
            (`geosyn.sim.mesh_clearance`, ``SimResult.mesh_clearance``); None: not
            checked (the result's note says so).

    Raises:
        InvalidArgument: a bad argument; the message names it.
        UnknownBody: a disturbance or payload names a body that is not in the scene.
    """

    def __init__(
        self,
        robot: Robot,
        controller: ControllerLike,
        *,
        control_dt: float = 1e-3,
        substeps: int = 1,
        integrator: str = "implicitfast",
        payloads: Sequence[Payload] = (),
        obstacles: Sequence[Any] = (),
        disturbances: Sequence[Disturbance] = (),
        gravity: Sequence[float] | None = None,
        seed: int = 0,
        contact: bool = False,
        torque_limits: bool = True,
        position_limits: bool = True,
        plant: str = "model",
        mesh_resolution: float | None = MESH_RESOLUTION,
    ) -> None:
        disturbances = check_parts(robot, controller, disturbances)
        self.plant = check_choice(plant, ("model", "file"), "plant")
        control_dt = check_positive(control_dt, "control_dt", "s")
        self.substeps = check_int(substeps, "substeps", low=1)
        self.seed = check_int(seed, "seed", low=0)
        self.robot = robot
        self.controller = controller
        self.control_dt = control_dt
        self.integrator = integrator
        self.torque_limits = bool(torque_limits)
        self._contact = bool(contact)
        build = build_file_scene if self.plant == "file" else build_scene  # same arguments
        self.scene: Scene = build(
            robot,
            timestep=control_dt / self.substeps,
            integrator=integrator,
            gravity=gravity,
            limits=position_limits,
            payloads=payloads,
            obstacles=obstacles,
            contact=contact,
        )
        self.model = self.scene.model
        self.data = mujoco.MjData(self.model)
        self.tau_min, self.tau_max = torque_range(self.scene, robot, self.plant, self.torque_limits)

        self.disturbances = copy.deepcopy(disturbances)
        for d in self.disturbances:
            d.bind(self.scene, control_dt)
        self._measure_hooks = [d for d in self.disturbances if overrides(d, "modify_measurement")]
        self._tau_hooks = [d for d in self.disturbances if overrides(d, "modify_tau")]
        self._tick_hooks = [d for d in self.disturbances if overrides(d, "on_tick")]
        self._pre_hooks = [d for d in self.disturbances if overrides(d, "before_tick")]
        self._zero_xfrc = any(d.applies_wrench for d in self.disturbances)
        self.divergence = DivergenceCheck(robot, self.data)
        shapes = [o.shape for o in self.scene.obstacles]
        self.mesh_check = RunClearance(robot, shapes, mesh_resolution)

    def _start(self, q0: Vector, v0: Vector, reference: ReferenceLike | None, seed: int) -> None:
        """Reset the model, the disturbances (reseeded) and the controller for a run."""
        children = np.random.SeedSequence(seed).spawn(len(self.disturbances))
        for dist, child in zip(self.disturbances, children, strict=True):
            dist.reset(np.random.default_rng(child))
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[self.scene.qpos_adr] = q0
        self.data.qvel[self.scene.dof_adr] = v0
        self.divergence.start()
        controller = self.controller
        if reference is not None:
            set_ref = getattr(controller, "set_reference", None)
            if not callable(set_ref):
                raise InvalidArgument(
                    f"a reference was given but controller {type(controller).__name__} has no set_reference()"
                )
            set_ref(reference)
        controller.reset(q0.copy(), v0.copy(), 0.0)

    # -- running ---------------------------------------------------------------------
    def run(
        self,
        q0: Sequence[float] | Vector,
        v0: Sequence[float] | Vector | None = None,
        duration: float = 1.0,
        reference: ReferenceLike | None = None,
        *,
        seed: int | None = None,
        spool_dir: str | os.PathLike[str] | None = None,
    ) -> SimResult:
        """Simulate ``round(duration / control_dt)`` control ticks from ``(q0, v0)``.

        Allocates the log arrays once (`geosyn.sim.log.allocate_rows`); the tick loop
        allocates only small vectors. A run of more than ``SPOOL_CHUNK`` ticks keeps one
        chunk of rows in memory and writes the others to a spool file as it runs
        (`geosyn.sim.log_spool`): its result's arrays are read-only maps of that file,
        which is removed from the directory when the run ends (or raises).

        Args:
            q0: (nq,) initial joint positions [rad].
            v0: (nv,) initial joint velocities [rad/s]; zero by default.
            duration: simulated time [s], at least one control period.
            reference: passed to ``controller.set_reference`` before the run. The
                reference logged at each tick is the controller's ``reference`` attribute
                when it has one (it may replan), else this one.
            seed: overrides the simulation's seed for this run.
            spool_dir: directory of a long run's spool file; None: the one set by
                `geosyn.sim.log_spool.spool_directory`, else the system's temporary one.

        Returns:
            The per-tick log; ``status`` says whether the run completed.

        Raises:
            InvalidArgument: bad initial state, duration (also: a log larger than
                `geosyn.sim.log_spool.MAX_LOG_BYTES`) or seed, the controller returned
                an array of the wrong shape or raised `InvalidArgument`. Other geosyn errors
                of the controller (a failed solve, no reference) end the run with the status
                ``"controller failed: ..."``.
            SpoolError: a long run's spool file cannot be written (e.g. disk full).
        """
        q0, v0, n_ticks, seed = self._check_run(q0, v0, duration, seed)
        dims = {"nq": self.robot.nq, "nv": self.robot.nv, "P": len(self.scene.payload_body_ids)}
        log = open_log(n_ticks, dims, self.control_dt, spool_dir)
        try:
            self._start(q0, v0, reference, seed)
            wall0 = time.perf_counter()
            status, done, status_codes = self._loop(log, n_ticks, reference)
            wall = time.perf_counter() - wall0
            rows = log.finish(done)
            mesh = self.mesh_check.measure(rows["t"], rows["q"])
        except BaseException:
            log.discard()  # a spool file never outlives a run that raised
            raise
        return self._result(rows, n_ticks, status, status_codes, wall, seed, mesh)

    def _check_run(
        self,
        q0: Sequence[float] | Vector,
        v0: Sequence[float] | Vector | None,
        duration: float,
        seed: int | None,
    ) -> tuple[Vector, Vector, int, int]:
        """The checked ``(q0, v0, number of ticks, seed)`` of a `run`."""
        nq, nv = self.robot.nq, self.robot.nv
        q0 = check_vector(q0, nq, "q0")
        v0 = np.zeros(nv) if v0 is None else check_vector(v0, nv, "v0")
        duration = check_positive(duration, "duration", "s")
        n_ticks = int(round(duration / self.control_dt))
        if n_ticks < 1:
            raise InvalidArgument(
                f"duration must be >= control_dt={self.control_dt} [s], got {duration!r}"
            )
        seed = check_int(self.seed if seed is None else seed, "seed", low=0)
        return q0, v0, n_ticks, seed

    def _loop(
        self, log: LogWriter, n_ticks: int, reference: ReferenceLike | None
    ) -> tuple[str, int, dict[str, int]]:
        """The control ticks of a `run` (see the module doc), logged into ``log``: tick
        ``k`` in row ``j`` of its buffers, a full chunk flushed to its spool file.

        One function on purpose: the tick is the hot path (tens of microseconds), so its
        steps stay inline on locals bound once here instead of costing a call each.

        Returns:
            (status, ticks done, solver status name -> code).
        """
        m, d, sc = self.model, self.data, self.scene
        nv = self.robot.nv
        pay_ids = sc.payload_body_ids
        n_pay = len(pay_ids)
        controller = self.controller
        has_ref_attr = hasattr(type(controller), "reference") or hasattr(controller, "reference")
        rows, chunk, flush = log.rows, log.chunk, log.flush
        t_log, q_log, v_log = rows["t"], rows["q"], rows["v"]
        qm_log, vm_log = rows["q_meas"], rows["v_meas"]
        tau_log, taua_log, sat_log = rows["tau"], rows["tau_applied"], rows["saturated"]
        qref_log, vref_log = rows["q_ref"], rows["v_ref"]
        ke_log, clear_log, pay_log = rows["kinetic_energy"], rows["clearance"], rows["payload_mass"]
        ctime_log, iter_log = rows["compute_time"], rows["iterations"]
        fb_log, st_log = rows["fallback_used"], rows["solver_status"]

        status_codes: dict[str, int] = {"": 0}
        rk4 = self.integrator == "RK4"
        dt = self.control_dt
        extra_steps = range(self.substeps if rk4 else self.substeps - 1)
        clip = self.torque_limits
        applied = self.plant == "file"
        lo, hi = self.tau_min, self.tau_max
        speed = self.divergence.speed_limit
        speed_sq = float(np.min(speed, initial=math.inf)) ** 2  # |v|^2 below it: all |v_i| are
        diverged = self.divergence.status
        qadr, dadr = sc.qpos_adr, sc.dof_adr
        clearance = sc.clearance if len(sc.obstacles) else None
        contact_log = rows["contact_force"]
        contact_geoms = frozenset(int(g) for g in sc.obstacle_geom_ids) if self._contact else None
        contact_buf = np.zeros(6)
        measure_hooks, tau_hooks = self._measure_hooks, self._tau_hooks
        tick_hooks, pre_hooks = self._tick_hooks, self._pre_hooks
        zero_xfrc = self._zero_xfrc
        h_phys = dt / self.substeps
        perf = time.perf_counter
        isfinite = math.isfinite
        mv = np.zeros(m.nv)
        ref = reference
        status = "ok"
        done = j = 0

        for k in range(n_ticks + 1):
            t = k * dt
            q = d.qpos[qadr]
            v = d.qvel[dadr]
            # Divergence of the state reached by the previous tick (cheap test first).
            # MuJoCo resets its data (time 0) on an instability; its counters are read when
            # the clock shows it, and once after the first tick (a reset there keeps time).
            reset = abs(d.time - t) > 0.5 * h_phys or k == 1
            within = float(v @ v) <= speed_sq or (np.abs(v) <= speed).all()
            if not (isfinite(float(q @ q)) and within) or reset:
                bad = diverged(t, q, v)
                if bad is not None:
                    status = bad
                    break
            if k == n_ticks:
                break
            d.time = t
            for h in pre_hooks:
                h.before_tick(t, m, d)
            if rk4:
                mujoco.mj_forward(m, d)
            else:
                mujoco.mj_step1(m, d)
            qm, vm = q, v
            for h in measure_hooks:
                qm, vm = h.modify_measurement(t, qm, vm)

            c0 = perf()
            try:
                out = controller.compute(t, qm, vm)
            except InvalidArgument:
                raise  # bad input is a bug in the setup, not an outcome of the run
            except GeosynError as err:
                status = f"controller failed: {type(err).__name__}: {err} at t={t:.6g} s"
                break
            c1 = perf()
            tau_cmd = np.asarray(out, dtype=np.float64)
            if tau_cmd.shape != (nv,) or not isfinite(float(tau_cmd @ tau_cmd)):
                status = self._bad_torque(tau_cmd, t)  # raises for a wrong shape
                break
            tau_out = tau_cmd
            for h in tau_hooks:
                tau_out = h.modify_tau(t, tau_out)
            if clip:  # the log's tau is the clipped command, tau_applied what the motors got
                tau_c = np.minimum(np.maximum(tau_cmd, lo), hi)
                tau_a = np.minimum(np.maximum(tau_out, lo), hi) if tau_hooks else tau_c
                sat_log[j] = tau_a != tau_out
            else:
                tau_c, tau_a = tau_cmd, tau_out
            diag = getattr(controller, "diagnostics", None)
            ctrl_sat = getattr(diag, "saturated", None)
            if ctrl_sat is not None and np.shape(ctrl_sat) == (nv,):
                sat_log[j] |= ctrl_sat  # the controller clipped its own command at the limits
            tau_log[j] = tau_c

            if zero_xfrc:
                d.xfrc_applied[:] = 0.0
            for h in tick_hooks:
                h.on_tick(t, m, d)
            if applied:
                d.qfrc_applied[dadr] = tau_a
            else:
                d.ctrl[:] = tau_a

            # -- log row k (kinematics and mass matrix are those of the tick's state)
            t_log[j] = t
            q_log[j] = q
            v_log[j] = v
            qm_log[j] = qm
            vm_log[j] = vm
            taua_log[j] = tau_a
            if has_ref_attr:
                ref = controller.reference  # type: ignore[attr-defined]
            if ref is not None:
                q_r, v_r, _ = ref.sample(t)
                qref_log[j] = q_r
                vref_log[j] = v_r
            qvel = d.qvel
            mujoco.mj_mulM(m, d, mv, qvel)
            ke_log[j] = 0.5 * float(qvel @ mv)
            if clearance is not None:
                clear_log[j] = clearance(d.xpos, d.xmat, q)
            if contact_geoms and rk4:  # mj_forward solved this tick's contact forces
                contact_log[j] = obstacle_contact_force(m, d, contact_geoms, contact_buf)
            if n_pay:
                pay_log[j] = m.body_mass[pay_ids]
            ctime_log[j] = c1 - c0
            if diag is not None:
                it = getattr(diag, "iterations", None)
                if it is not None:
                    iter_log[j] = it
                fb_log[j] = getattr(diag, "fallback_used", False)
                st = getattr(diag, "solver_status", None)
                if st is not None:
                    key = str(getattr(st, "name", st))
                    st_log[j] = status_codes.setdefault(key, len(status_codes))
            done = k + 1

            # -- physics over the tick
            if not rk4:
                mujoco.mj_step2(m, d)
                # the constraint forces of the contacts mj_step1 found are solved only now
                # (before mj_step2, efc_force is the previous step's, or unset at t=0)
                if contact_geoms:
                    contact_log[j] = obstacle_contact_force(m, d, contact_geoms, contact_buf)
            for _ in extra_steps:
                mujoco.mj_step(m, d)
            j += 1
            if j == chunk:  # a long run's full chunk: to disk, the buffers reused
                flush(j)
                j = 0

        return status, done, status_codes

    def _bad_torque(self, tau: np.ndarray, t: float) -> str:
        """The status of a run whose controller returned a non-finite torque ``tau`` at
        ``t`` [s]; `InvalidArgument` if ``tau`` has the wrong shape (a setup bug)."""
        if tau.shape != (self.robot.nv,):
            raise InvalidArgument(
                f"controller {type(self.controller).__name__}.compute returned shape"
                f" {tau.shape}, expected ({self.robot.nv},)"
            )
        return f"diverged: controller returned a non-finite torque {tau} at t={t:.6g} s"

    def _result(
        self,
        rows: dict[str, np.ndarray],
        n_ticks: int,
        status: str,
        status_codes: dict[str, int],
        wall: float,
        seed: int,
        mesh: MeshClearance,
    ) -> SimResult:
        """The `SimResult` of a run: its finished ``rows``, the run's metadata and its
        exact clearance ``mesh``."""
        d, sc, dt = self.data, self.scene, self.control_dt
        return SimResult(
            **rows,
            q_final=d.qpos[sc.qpos_adr].copy(),
            v_final=d.qvel[sc.dof_adr].copy(),
            solver_status_names=tuple(status_codes),
            joint_names=tuple(self.robot.joint_names),
            robot_name=self.robot.name,
            control_dt=dt,
            substeps=self.substeps,
            integrator=self.integrator,
            duration=float(n_ticks * dt),
            status=status,
            wall_time=wall,
            seed=seed,
            controller_notes=controller_notes(self.controller),
            mesh_clearance=mesh.clearance,
            mesh_clearance_note=mesh.note,
        )


__all__ = ["SPEED_FACTOR", "ControllerLike", "ReferenceLike", "Simulation"]
