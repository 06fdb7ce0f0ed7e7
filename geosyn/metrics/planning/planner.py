"""`Planner`: minimum-energy, collision-free motion between two configurations.

One query, within a stated time budget:

1. checks the input: start and goal within the joint limits and collision-free (else
   `OutsideJointLimits` / `InCollision` naming the obstacle and the robot sphere), at most
   ``capacity`` obstacles (else `geosyn.metrics.shaping.CapacityExceeded`);
   then a sampled first plan without an NLP, for the anytime return (RRT-Connect on the
   spheres, in C: `geosyn.metrics.planning.sampling`; pulled taut in the metric,
   `geosyn.metrics.planning.sampled`, and on the exact geometry, `tighten`; verified as
   in 4.: `geosyn.metrics.planning.query`), also RRT-Connect's first seed in 3.; with
   less than `query.MIN_COLLOCATION` left after it, or among obstacles when `collocates`
   is False, the rest of the budget relaxes it further and tries other seeds (bumped
   straight lines and RRT-Connect paths by turns, `polish`; the same on a thinner sphere
   model pushed out on the exact geometry, `thin`) instead of 2.-3.; with more, the
   same for `query.POLISH_FIRST` of it first;
2. collocation (`geosyn.metrics.geodesic.collocation.Collocation`) from the straight line,
   coarse to fine when there are obstacles: a collocation with few nodes
   (``coarse_nodes``, points inside each segment ``coarse_subdivisions``) from the
   straight line, keeping an inflated clearance ``margin + coarse_inflation`` (so that
   its widely spaced points do not straddle thin obstacles; lowered near start and goal
   to their own clearances), then the full collocation from its path, interpolated, with
   a small initial barrier parameter (``seeded_mu_init``), within the first
   `COARSE_TO_FINE` of the budget (`geosyn.metrics.planning.coarse`); if the
   coarse-to-fine plan fails (other than by running out of that time), the full
   collocation from the straight line itself;
3. if that fails, RRT-Connect (`geosyn.metrics.planning.rrt`) for a global seed around
   the obstacles, then collocation from it; after a constrained straight-line result,
   up to ``alternatives`` RRT-Connect seeds (other homotopy classes round the
   obstacles), each while the time left is at least the time the first plan took
   (and bounded by about three times that), keeping the lowest-energy plan not longer than the straight line's
   (`geosyn.metrics.planning.query`);
4. checks the result between the nodes (``check_factor`` times finer and at most
   ``check_step`` apart, linear between nodes) and, for a robot with a file, against its
   exact collision geometry (`geosyn.metrics.planning.verify`: coal distances to the
   file's meshes every ``exact_resolution`` rad, which then decide); a path that touches
   an obstacle is solved again with more constrained points (`REFINEMENTS`) and, after an
   exact failure, a sphere margin larger by the penetration plus `REPAIR_STEP`, until one
   passes, or refused; and for self-collision on the file's self pairs
   (`geosyn.metrics.planning.self_path.path_self_contact`, same resolution): a
   self-colliding path is refused (the sampled plans avoid it: their validity includes
   the self pairs' sphere distances, a pair's floor raised for the rest of the query
   near where the exact check found its links touching), never returned. Every plan keeps
   the joint limits at every sample (the box is convex, so between them too): the
   collocation has them as bounds, the relaxations of the sampled plans take projected steps
   (`geosyn.metrics.planning.relax.metric_relax`'s ``bounds``), and the verification
   refuses a path that leaves them (`geosyn.metrics.planning.verify.outside_limits`).

Default spheres: fitted to the file's meshes (`geosyn.robots.collision_spheres`); they
and the NLP's per-node functions are cached on disk (`collocation_nlp`).

A query that cannot succeed raises `NoPathFound` once the budget is spent, listing what
was tried. The NLPs are built once (their obstacle poses are parameters), so every scene
of one robot and capacity reuses them.
"""

from __future__ import annotations

import functools
import math
import time
import warnings
from collections.abc import Callable, Sequence

import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_float, check_int, check_positive, check_vector
from geosyn.metrics.base import Metric, check_metric
from geosyn.metrics.geodesic.collocation import Collocation, CollocationResult
from geosyn.metrics.planning.anytime import ANYTIME_CHECKS
from geosyn.metrics.planning.certify import CertifiedClearance, certified_plan, planner_certificate
from geosyn.metrics.planning.coarse import clearance_bounds
from geosyn.metrics.planning.goals import EndEffectorGoal, plan_to_goal
from geosyn.metrics.planning.nlp_slots import NlpSlots
from geosyn.metrics.planning.plan import Plan
from geosyn.metrics.planning.query import (
    ANYTIME_SLACK,
    COARSE_TO_FINE,
    MIN_COLLOCATION,
    REFINEMENTS,
    Query,
)
from geosyn.metrics.planning.sampling import Sampling
from geosyn.metrics.planning.self_collision import SelfCollision, check_self_end
from geosyn.metrics.planning.self_path import SelfContact, path_self_contact
from geosyn.metrics.planning.smoothing import densify
from geosyn.metrics.planning.thin import THIN_SHRINKS, ThinSearch
from geosyn.metrics.planning.tighten import exact_movable
from geosyn.metrics.planning.verify import check_end, planning_geometry
from geosyn.metrics.shaping.obstacle import ObstacleTerm
from geosyn.robots.robot import CollisionSphere
from geosyn.world.shapes import Shape

__all__ = [
    "ANYTIME_CHECKS",
    "ANYTIME_SLACK",
    "COARSE_TO_FINE",
    "REFINEMENTS",
    "Plan",
    "Planner",
    "densify",
]


class Planner:
    """Collision-free minimum-energy paths of one robot among up to ``capacity`` obstacles.

    Args:
        metric: velocity-independent metric with a ``robot`` (e.g. `KineticEnergyMetric`).
        capacity: obstacle slots, >= 1.
        spheres: robot collision spheres; None: spheres fitted to the robot file's own
            collision geometry (`geosyn.robots.collision_spheres.file_spheres`, cached on
            disk; those on the fixed base left out: their clearance cannot change, and
            the exact check covers them), or ``robot.collision_spheres()`` for a robot
            built in code. Given spheres (e.g. with a held object's) are kept clear as
            well as the file's geometry: paths keep the margin on them (not moved nearer
            the meshes), verified on both.
        exact_resolution: joint-space step (max-norm) [rad] of the exact verification of
            every returned plan against the file's geometry, > 0.
        margin: node clearance of the collocation [m], >= 0 (on the spheres); a sampled
            plan is tightened to it on the spheres, then on the robot's own geometry
            (`geosyn.metrics.planning.tighten`: penalised below it, never below half).
        nodes: segments of the collocation, >= 2.
        check_factor: refinement of the between-node check, >= 1.
        check_step: largest joint-space distance (2-norm) between two checked
            configurations [rad], > 0.
        alternatives: RRT-Connect seeds collocated after a constrained straight-line
            plan (when the query `collocates`), >= 0, each only while the time left of
            the budget is at least the time the first plan took (each costs a sampling
            bounded by that time and a collocation bounded by twice that); the
            lowest-energy plan whose metric length is not above the straight line's
            wins. 0: the first plan is returned once found.
        coarse_nodes: segments of the coarse collocation that seeds the full one when
            there are obstacles, >= 2; 0: none (the full collocation from the straight line).
        coarse_subdivisions: constrained points inside each coarse segment, >= 0.
        coarse_inflation: the coarse collocation keeps clearance ``margin`` plus this
            [m], >= 0; the sum is the attribute ``coarse_margin``.
        seeded_mu_init: IPOPT's initial barrier parameter of the full collocation from the
            coarse path, > 0 (IPOPT's default 0.1 first pushes a path already near a
            solution far from the obstacles).
        compile: what to compile to C (cached on disk): see `Collocation`.
        distance: signed distance of the clearance constraints, ``"exact"`` or
            ``"smooth"`` (see `geosyn.metrics.shaping.obstacle.DISTANCES`).
        hessian, tol, softmin: see `Collocation`.
        prebuild: obstacle count whose NLPs are built with the planner when its queries
            collocate (`collocates`), >= 0 (`slots`; other counts' on their first query
            that collocates, or with `prepare`).

    Builds the collocation NLPs of ``prebuild`` obstacles (allocates; see `Collocation`).
    """

    def __init__(
        self,
        metric: Metric,
        *,
        capacity: int = 8,
        spheres: Sequence[CollisionSphere] | None = None,
        margin: float = 0.01,
        nodes: int = 24,
        check_factor: int = 4,
        check_step: float = 0.005,
        alternatives: int = 2,
        coarse_nodes: int = 4,
        coarse_subdivisions: int = 3,
        coarse_inflation: float = 0.015,
        seeded_mu_init: float = 1e-4,
        compile: bool | str = False,
        distance: str = "exact",
        hessian: str = "exact",
        tol: float = 1e-8,
        softmin: float | None = 1000.0,
        exact_resolution: float = 0.005,
        prebuild: int = 1,
    ) -> None:
        t0 = time.perf_counter()
        prebuild = check_int(prebuild, "prebuild", low=0)
        self.metric = check_metric(metric)
        robot = getattr(metric, "robot", None)
        if robot is None:
            raise InvalidArgument("metric: the planner needs a metric with a robot")
        self.robot = robot
        self.exact_resolution = check_positive(exact_resolution, "exact_resolution", "rad")
        self.given_spheres = spheres is not None  # then kept clear too (`Query.decide`)
        spheres, self.exact, self.geometry_note = planning_geometry(robot, spheres)
        if self.geometry_note:  # said once, at build: every plan of this planner is so
            warnings.warn(f"Planner: {self.geometry_note}", UserWarning, stacklevel=2)
        self.term = ObstacleTerm((), capacity=capacity, spheres=spheres, distance=distance)
        self.term.bind(robot)
        self.margin = check_float(margin, "margin", low=0.0)
        self.sampling = Sampling(robot, spheres, self.exact, 0.5 * self.margin)
        self.sphere_check = self.sampling.check  # self pairs on the file's spheres
        self.nodes = check_int(nodes, "nodes", low=2)
        self.check_factor = check_int(check_factor, "check_factor", low=1)
        self.check_step = check_positive(check_step, "check_step", "rad")
        self.alternatives = check_int(alternatives, "alternatives", low=0)
        self.coarse_nodes = check_int(coarse_nodes, "coarse_nodes", low=0)
        if self.coarse_nodes == 1:
            raise InvalidArgument("coarse_nodes: 0 (no coarse stage) or >= 2, got 1")
        self.coarse_subdivisions = check_int(coarse_subdivisions, "coarse_subdivisions", low=0)
        inflation = check_float(coarse_inflation, "coarse_inflation", low=0.0)
        self.coarse_margin = self.margin + inflation
        self.seeded_mu_init = check_positive(seeded_mu_init, "seeded_mu_init")
        self.compile = compile
        self.hessian = hessian
        self.tol = check_positive(tol, "tol")
        self.softmin = softmin
        self.nlps = NlpSlots(self.metric, robot, self.term, spheres, distance,
                             margin=self.margin, compile=compile, hessian=hessian,
                             tol=self.tol, softmin=softmin)  # fmt: skip
        if self.collocates(prebuild):  # others on their first query that collocates
            self.prepare(prebuild)
        if self.sphere_check.self_pairs:  # every query checks its ends with it: built now
            _ = self.self_collision
        self.build_time = time.perf_counter() - t0

    def _build_nlps(self) -> None:
        """Build the NLPs every query of the current slot count uses (and the clearance
        function of its `bounds`)."""
        if not self.nlps.has(self.term.capacity):
            self.term.clearances(
                np.clip(np.zeros(self.metric.n), self.robot.q_min, self.robot.q_max)
            )
        self.collocation(self.nodes)
        if self.coarse_nodes:
            self.collocation(self.coarse_nodes, self.coarse_subdivisions)
            self.collocation(self.nodes).solver(self.seeded_mu_init)

    def slots(self, count: int) -> int:
        """Obstacle slots of the NLPs a query with ``count`` obstacles solves
        (`geosyn.metrics.planning.nlp_slots`), built with the planner (``prebuild``) or
        on its first query that `collocates` with a budget over `query.MIN_COLLOCATION`
        (`Plan.nlp_build_time`, or `prepare`; a smaller budget never collocates: a first
        free Panda query of 0.1 s took 0.2 s more building them, measured)."""
        return self.nlps.slots(count)

    def prepare(self, count: int) -> float:
        """Build now the NLPs of queries with ``count`` obstacles (>= 0), rather than on
        the first such query; the time spent [s] (0 when they exist)."""
        count = check_int(count, "count", low=0)
        try:
            return self._use_slots(count)
        finally:
            self.term = self.nlps.full

    def collocates(self, count: int) -> bool:
        """Whether a query among ``count`` obstacles solves collocations when its budget
        allows (`query.MIN_COLLOCATION`): without obstacles, or when the paths cannot be
        moved on the robot's own geometry (no file geometry, margin 0 or given spheres:
        `geosyn.metrics.planning.tighten.exact_movable`). Else the sampled plan, tightened
        on the meshes, is polished with the whole budget (`query.Query.collocates`)."""
        return count == 0 or not exact_movable(self)

    def _use_slots(self, count: int, nlps: bool = True) -> float:
        """Make the NLPs of ``slots(count)`` the current ones (``term`` and
        `collocation`; built now when ``nlps``, else on first use); the time [s] spent
        building them (0 when built before)."""
        t0 = time.perf_counter()
        self.term, built = self.nlps.term(count), self.nlps.built()
        if nlps:
            self._build_nlps()
        return time.perf_counter() - t0 if self.nlps.built() > built else 0.0

    @functools.cached_property
    def thin(self) -> tuple[ThinSearch, ...]:
        """The thinner sphere models of the polishing's extra seeds, one a round
        (`geosyn.metrics.planning.thin.THIN_SHRINKS`; built on first use, a few ms)."""
        return tuple(ThinSearch.for_planner(self, shrink) for shrink in THIN_SHRINKS)

    @functools.cached_property
    def self_collision(self) -> SelfCollision | None:
        """Exact self-clearance on the file's self-collision pairs (built with the
        planner when it has self pairs, not in a query's budget: ~70 ms on the Panda), or
        None for a robot without file geometry."""
        return SelfCollision.for_robot(self.robot) if self.exact is not None else None

    def collocation(self, nodes: int, subdivisions: int = 1) -> Collocation:
        """The collocation with ``nodes`` segments and ``subdivisions`` constrained points
        inside each, for the current obstacle slots (built on first use, then kept)."""
        return self.nlps.collocation(self.term, nodes, subdivisions)

    def check(
        self, path: np.ndarray, smooth: bool = True, fine: bool = True
    ) -> tuple[float, float]:
        """Smallest clearances [m] of ``path`` (T, n), linear between its samples, checked
        ``check_factor`` times finer, and at most ``check_step`` apart (2-norm; NaN when
        not ``fine``: a sampled plan that the exact check decides): by the constraints'
        smooth minimum, or (``smooth`` False, for sampled plans, a few times cheaper) the
        exact sphere distances (`SphereCheck`)."""
        path = np.asarray(path, dtype=float)
        step = float(np.linalg.norm(np.diff(path, axis=0), axis=1).max(initial=0.0))
        factor = max(self.check_factor, math.ceil(step / self.check_step))
        clearances: Callable[[np.ndarray], np.ndarray] = self.sphere_check.clearances
        if smooth:  # the NLP's own (built on first use)
            clearances = self.collocation(self.nodes).node_clearances
        else:
            self.sphere_check.set_obstacles(self.term.obstacles)
        coarse = float(clearances(densify(path, self.check_factor)).min())
        if not fine:
            return coarse, math.nan
        return coarse, float(clearances(densify(path, factor)).min())

    def valid(self, Q: np.ndarray) -> np.ndarray:
        """(K,) True where the configurations ``Q`` (K, n) [rad] are valid for sampling
        (`Sampling.valid`, the planner's obstacles)."""
        self.sampling.set_obstacles(self.term.obstacles)
        return self.sampling.valid(Q)

    def segment_valid(self, a: np.ndarray, b: np.ndarray, resolution: float) -> bool:
        """Whether the joint segment ``a`` -> ``b`` (n,) [rad] is valid every
        ``resolution`` [rad] (`Sampling.segment_valid`, the planner's obstacles)."""
        self.sampling.set_obstacles(self.term.obstacles)
        return self.sampling.segment_valid(a, b, resolution)

    def self_check(self, path: np.ndarray, deadline: float = math.inf) -> float:
        """Self-clearance [m] of ``path`` (T, n) [rad] at ``exact_resolution``
        (`path_self_contact`; NaN without file geometry or past ``deadline``)."""
        return self.self_contact(path, deadline)[0]

    def self_contact(self, path: np.ndarray,
                     deadline: float = math.inf) -> tuple[float, SelfContact | None]:  # fmt: skip
        """`self_check` and, when negative, where the links intersect
        (`path_self_contact`)."""
        checker = self.self_collision if self.sphere_check.self_pairs else None
        return path_self_contact(checker, self.sphere_check, path, self.exact_resolution,
                                 deadline, self.sampling.aids.kinematics)  # fmt: skip

    def self_ok(self, clearance: float) -> bool:
        """Whether a path of that `self_check` value may be returned: not negative, and
        decided (NaN only for a robot without file geometry)."""
        if not self.sphere_check.self_pairs:
            return True
        return clearance >= 0.0

    def bounds(self, col: Collocation, q0: np.ndarray, q1: np.ndarray, level: float) -> np.ndarray:
        """(P, m) clearance bounds [m] of the collocation ``col`` at its points, at
        ``level`` [m] (`geosyn.metrics.planning.coarse.clearance_bounds`)."""
        return clearance_bounds(self, col, q0, q1, level)

    def coarse_bounds(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """(P, m) clearance bounds [m] of the coarse collocation (`bounds` at
        ``coarse_margin``)."""
        col = self.collocation(self.coarse_nodes, self.coarse_subdivisions)
        return self.bounds(col, q0, q1, self.coarse_margin)

    def solve(
        self, col: Collocation, q0: np.ndarray, q1: np.ndarray, **options: object
    ) -> CollocationResult:
        """``col.solve`` with the clearance `bounds` at ``margin`` (or ``options["lower"]``)."""
        if "lower" not in options:
            options["lower"] = self.bounds(col, q0, q1, self.margin)
        return col.solve(q0, q1, **options)  # type: ignore[arg-type]

    def certify(
        self, path: np.ndarray, obstacles: Sequence[Shape], *, target: float = 0.0
    ) -> CertifiedClearance:
        """The clearance of ``path`` (T, n) [rad] (e.g. ``plan.q``) to ``obstacles``
        certified between its configurations checked ``exact_resolution`` apart, on the
        robot file's own collision geometry (`geosyn.metrics.planning.certify`: a bound
        of how far any point of the robot moves between them; segments halved until
        their bound reaches ``target`` [m], >= 0). Not part of a query's budget (4-40 ms
        on the Panda benchmark scenes, measured).

        Raises:
            InvalidArgument: the robot has no file geometry (nothing exact to certify).
        """
        return planner_certificate(self, path, obstacles, target)

    def _check_end(self, q: np.ndarray, which: str) -> None:
        check_end(self.robot, self.term, self.exact, q, which)
        if self.sphere_check.self_pairs:
            check_self_end(self.self_collision, self.sphere_check, q, which)

    def plan(
        self,
        q0: Vector,
        q1: Vector | EndEffectorGoal,
        obstacles: Sequence[Shape] = (),
        *,
        budget: float = 5.0,
        seed: int = 0,
        certify: bool = False,
    ) -> Plan:
        """Plan from ``q0`` to ``q1`` around ``obstacles`` within ``budget`` seconds.

        Args:
            q0: (n,) start [rad].
            q1: (n,) goal [rad], or an end-effector position or pose with tolerances
                (`EndEffectorGoal`: solved by inverse kinematics within the limits and
                clear of the scene, several solutions planned to, the lowest-energy plan
                kept; see `geosyn.metrics.planning.goals`).
            obstacles: shapes of `geosyn.world`, at most ``capacity``.
            budget: wall-time limit of the query [s], > 0 (a shooting refinement of a
                free geodesic may add its own bounded iterations). When less than
                `query.MIN_COLLOCATION` (2.5 s) is left after the sampled first plan, or
                among obstacles on a robot with file geometry (the sampled plan is
                tightened on its meshes, `query.Query.collocates`), the plan is a sampled
                path pulled taut in the metric (``result.kind`` ``"feasible"``, verified
                like every plan; the query returns when its seeds stop paying, often well
                before the budget); else collocation makes the minimum-energy path
                (``"constrained"`` or ``"geodesic"``).
            seed: seed of the sampling fallback.
            certify: also certify the returned path between its checked configurations
                (`certify`, after the budget: ``plan.certified_clearance``); a path
                found colliding there is refused (`NoPathFound`), never returned.

        Returns:
            The plan; ``plan.result.kind`` says whether it is a geodesic or a
            minimum-energy constrained path.

        Raises:
            OutsideJointLimits: start or goal outside the limits.
            InCollision: start or goal in collision (names obstacle and sphere).
            geosyn.metrics.shaping.CapacityExceeded: more obstacles than ``capacity``.
            NoPathFound: no collision-free path within the budget.
            GoalUnreachable: no IK solution of an end-effector goal.
        """
        t0 = time.perf_counter()
        n = self.metric.n
        q0 = check_vector(q0, n, "q0")
        obstacles = tuple(obstacles)
        if isinstance(q1, EndEffectorGoal):
            budget, seed = check_positive(budget, "budget", "s"), check_int(seed, "seed")
            plan = plan_to_goal(self, q0, q1, obstacles, budget=budget, seed=seed)
            return certified_plan(self, plan, obstacles, budget) if certify else plan
        q1 = check_vector(q1, n, "q1")
        budget = check_positive(budget, "budget", "s")
        seed = check_int(seed, "seed")
        # built only for a query that may collocate; the budget's clock starts after it
        nlps = self.collocates(len(obstacles)) and budget > MIN_COLLOCATION
        built = self._use_slots(len(obstacles), nlps)
        try:
            self.term.set_obstacles(obstacles)
            self._check_end(q0, "start")
            self._check_end(q1, "goal")
            self.sampling.start(obstacles, q0, q1)
            plan = Query(self, q0, q1, budget, seed, t0 + built).run()
        finally:  # ``term`` holds the last query's obstacles, on every slot
            self.sampling.finish()
            if self.term is not self.nlps.full:
                self.nlps.full.set_obstacles(obstacles)
            self.term = self.nlps.full
        plan = plan._replace(nlp_build_time=built)
        return certified_plan(self, plan, obstacles, budget) if certify else plan
