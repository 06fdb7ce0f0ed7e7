"""`Query`: one planning query of a `Planner`, from a checked start and goal to a `Plan`.

Anytime: a query first makes a plan without an NLP (`Query.sampled`): RRT-Connect on
the planner's spheres (in C, within `SAMPLED_SEARCH`; the straight line when it is free
on them), pulled taut in the metric (`geosyn.metrics.planning.sampled.pull_taut`, within
`SAMPLED_RELAX` of the budget) and verified like every plan (the exact check decides,
self-collision included; one that fails is made again from other RRT-Connect seeds,
`SAMPLED_RETRIES`; after a self-collision with that pair's floor raised near it, `Query.retry`,
and then until the time is spent, even when collocation has time: its NLP has no
self-collision term).
The collocation stages then get the time left: none when less than `MIN_COLLOCATION` is
left, nor among obstacles when the paths can be moved on the exact geometry
(`Query.collocates`): the sampled plan is then polished (`Query.polish`: other seeds
pulled taut, bumped straight lines and RRT-Connect paths by turns, and seeds on a thinner
sphere model pushed out on the exact geometry, `geosyn.metrics.planning.thin`); with
more, it is polished so for `POLISH_FIRST` of the budget before the collocations start.
The kept plan is the best verified one by the homotopy rule below (the sampled plan is
one of the "other seeds": never kept when longer than the straight line's solution).
``Plan.first_feasible_time`` says when the first verified plan was found.

The query's clock, the list of what was tried and the unfinished paths kept for an
anytime return live here; the planner (its NLPs, checks and clearance bounds) is shared
by every query. The order of the search is stated in `geosyn.metrics.planning.planner`.

Homotopy rule (`geosyn.metrics.planning.homotopy`): after a constrained plan from the
straight line, up to ``planner.alternatives`` RRT-Connect seeds (other ways round the
obstacles) are solved, each only while the time left is at least the time the first plan
took (a solve from a seed costs about as much), its sampling bounded by that time and its
collocation by twice that (so a seed that does not connect cannot take the rest of a long
budget); the kept plan is the lowest-energy one not longer than the straight line's.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

import numpy as np

from geosyn.metrics.geodesic.collocation import CollocationResult
from geosyn.metrics.planning.anytime import anytime_plan
from geosyn.metrics.planning.coarse import coarse_to_fine
from geosyn.metrics.planning.errors import NoPathFound
from geosyn.metrics.planning.homotopy import alternative_plans, kept_plan
from geosyn.metrics.planning.plan import Plan
from geosyn.metrics.planning.polish import sphere_polish
from geosyn.metrics.planning.rrt import shortcut
from geosyn.metrics.planning.sampled import (
    SAMPLED_CHECK_SHARE,
    SAMPLED_RELAX,
    SAMPLED_RELAX_MAX,
    SAMPLED_RETRIES,
    SAMPLED_SEARCH,
    SAMPLED_SMALL,
    exact_line,
    pull_taut,
)
from geosyn.metrics.planning.sampling import sampling_box
from geosyn.metrics.planning.smoothing import even_in_metric
from geosyn.metrics.planning.thin import THIN_FIRST, thinner_plan
from geosyn.metrics.planning.tighten import EXACT_KEEP, exact_movable
from geosyn.metrics.planning.verify import (
    REPAIR_STEP,
    deciding_clearance,
    exact_check,
    feasible_result,
    outside_limits,
)

if TYPE_CHECKING:
    from geosyn.metrics.planning.planner import Planner
    from geosyn.metrics.planning.self_path import SelfContact
    from geosyn.world.exact_clearance import PathClearance

__all__ = [
    "ANYTIME_SLACK",
    "COARSE_TO_FINE",
    "MIN_COLLOCATION",
    "POLISH_FIRST",
    "POLISH_FIRST_MAX",
    "REFINEMENTS",
    "Query",
]

ANYTIME_SLACK = 1.05
"""Those checks stop at this multiple of the budget (an unchecked path is not returned)."""

REFINEMENTS = ((1, 3), (2, 1), (2, 3))
"""What a path that fails the fine check is solved again with, in turn, from the same
seed: (node count as a multiple of ``nodes``, constrained points inside each segment)."""


MIN_COLLOCATION = 2.5
"""Time left [s] below which no collocation is started once a sampled plan is verified:
the time goes to relaxing it and to other seeds (`Query.polish`). A Panda
collocation among obstacles takes 0.5-2.5 s (`benchmarks/RESULTS.md`: at 1-2 s budgets
it finished on fewer than half of the 14 benchmark scenes), where a relaxed sampled
plan comes within a few per cent of its length in 0.1-0.3 s."""

COARSE_TO_FINE = 0.8
"""Share of the budget left after the sampled plan that the coarse-to-fine collocation
may take (the coarse solve half of it); when the clock stops it, the full collocation from the straight line (a colder
start with less time) is skipped and the time left goes to RRT-Connect."""

POLISH_FIRST = 0.2
"""Share of a budget that leaves time for collocation (at most `POLISH_FIRST_MAX`) in
which the sampled plan is polished (`Query.polish`) before the collocations start: a
larger budget then keeps the sampled plan a smaller one returns, where the covering
spheres keep a collocated path up to 2 cm farther from the meshes than needed (without
it, the default 5 s budget's plans were 1.1-3.2 % longer than a 1 s budget's on 5 of
the 14 Panda benchmark scenes, measured)."""

POLISH_FIRST_MAX = 1.0
"""Longest polishing [s] of the sampled plan before the collocations."""


class Query:
    """One query of ``planner`` from ``q0`` to ``q1`` (checked, obstacles set) within
    ``budget`` [s] from ``t0`` (perf_counter [s]); `run` returns the plan or raises."""

    def __init__(self, planner: Planner, q0: np.ndarray, q1: np.ndarray, budget: float,
                 seed: int, t0: float) -> None:  # fmt: skip
        self.p, self.q0, self.q1 = planner, q0, q1
        self.budget, self.seed, self.t0 = budget, seed, t0
        eased = planner.sampling.ramp_line  # `Sampling.start`'s
        self.attempts: list[str] = [eased] if eased else []
        self.unfinished: list[tuple[np.ndarray, str]] = []  # interrupted iterates and seeds
        self.first = math.nan  # when the first plan passed every check [s]
        self.sampled_path: np.ndarray | None = None  # the sampled plan's path
        self.first_path: np.ndarray | None = None  # the first one (RRT-Connect seed 0)
        self.check_time = 0.0  # the last sampled plan's checks took [s]
        self.restart = 1  # the polishing's next seed (`taut_seeds`): a second one goes on
        self.exact_failed = False  # the last sampled plan crossed the exact geometry
        self.floor = math.nan  # the given spheres' clearance allowed (`decide`)
        self.contact: SelfContact | None = None  # where the last sampled plan self-collided
        self.self_collided = False  # one did: the retries go on (the NLP has no term for it)
        self.learning = True  # `retry` may raise self floors
        self.connected = False  # the last sampled plan's RRT-Connect found a path

    def decide(self, exact: PathClearance, spheres: float) -> tuple[float, str]:
        """`deciding_clearance` of a path of this query (its exact check, its smallest
        sphere clearance [m]): the given spheres down to their clearance at the ends."""
        p = self.p
        if p.given_spheres and math.isnan(self.floor):  # once, with the obstacles set
            p.sphere_check.set_obstacles(p.term.obstacles)
            ends = p.sphere_check.clearances(np.array([self.q0, self.q1]))
            self.floor = min(0.0, float(np.min(ends, initial=math.inf)))
        exact_or_none = exact if p.exact is not None else None
        return deciding_clearance(exact_or_none, spheres, p.given_spheres, self.floor)

    def left(self) -> float:
        """Time left of the budget [s] (negative once spent)."""
        return self.budget - (time.perf_counter() - self.t0)

    def reserve(self) -> float:
        """Time [s] a polishing keeps back for one final check (1.5 times the last one's)."""
        return 1.5 * self.check_time + 0.005

    def finish(self, res: CollocationResult, init: np.ndarray | None, seed_name: str,
               share: float) -> Plan | None:  # fmt: skip
        """The plan if ``res`` passes the fine check, else solved again from the same
        seed ``init`` along `REFINEMENTS` (within the first ``share`` of the budget)
        until one does. Not from ``res``: where a thin obstacle lies between two
        constrained points, a finer NLP started there keeps the crossing (measured)."""
        p, previous, extra = self.p, -math.inf, 0.0
        for level, (_, sub) in enumerate(((1, 1), *REFINEMENTS)):
            if why := outside_limits(p.robot, res.q):  # the NLP's bounds: not expected
                self.attempts.append(f"{res.kind} path leaves the joint limits ({why}): refused")
                return None
            coarse, fine = p.check(res.q)
            exact = exact_check(
                p.exact, res.q, p.term.obstacles, p.exact_resolution, aids=p.sampling.aids
            )
            check, what = self.decide(exact, min(coarse, fine))
            own = p.self_check(res.q) if check >= 0.0 else math.nan
            if check >= 0.0 and not p.self_ok(own):  # no NLP term for it: refused
                self.attempts.append(f"{res.kind} path self-collides (exact self-clearance "
                                     f"{own:.4f} m): refused")  # fmt: skip
                return None
            if check >= 0.0:
                wall = time.perf_counter() - self.t0
                self.first = wall if math.isnan(self.first) else self.first
                return Plan(res, seed_name, coarse, wall, tuple(self.attempts), fine,
                            exact.clearance, p.exact_resolution, self.first,
                            self_clearance=own)  # fmt: skip
            self.attempts.append(
                f"{res.kind} path ({len(res.nodes) - 1} segments, {sub} constrained "
                f"point(s) inside each) crosses an obstacle on {what} (clearance {check:.4f} m)"
            )
            if p.exact is not None:  # repair: a larger sphere margin, and more points
                extra += -check + REPAIR_STEP
            if level == len(REFINEMENTS):
                return None
            if level >= 2 and check <= 0.5 * previous:  # after more nodes, too
                self.attempts.append("refining does not help: the path tunnels through")
                return None
            previous = max(previous, check)
            nodes, sub = p.nodes * REFINEMENTS[level][0], REFINEMENTS[level][1]
            col = p.collocation(nodes, sub)  # its first use builds it: then the clock
            if (share_left := self.left() - (1.0 - share) * self.budget) <= 0:
                self.attempts.append("no time left to refine it")
                return None
            res = p.solve(col, self.q0, self.q1, init=init, budget=share_left,
                          lower=p.bounds(col, self.q0, self.q1, p.margin + extra))  # fmt: skip
            if not res.success:
                self.attempts.append(f"collocation ({nodes} segments, {sub} constrained "
                                     f"point(s) inside each): {res.message}")  # fmt: skip
                return None
        return None

    def connect(self, index: int, budget: float) -> tuple[np.ndarray | None, int]:
        """RRT-Connect seed ``seed + index`` within ``budget`` [s] (`rrt_connect`)."""
        p, q0, q1 = self.p, self.q0, self.q1
        lo, hi = sampling_box(p.robot, q0, q1)
        return p.sampling.connect(q0, q1, lo, hi, budget, self.seed + index)

    def sampled(self, index: int = 0) -> Plan | None:
        """The first plan without an NLP (module docstring; where RRT-Connect finds no
        connection on the spheres, the straight line if the exact geometry passes it,
        `exact_line`), or None; its path (when RRT-Connect found one round the
        obstacles) is kept as the seed of
        `from_rrt` (0). ``index`` > 0: again, from RRT-Connect seed ``seed + index``
        searched for at most half the time left, after plans that failed their checks
        (`run`)."""
        a, b, c = SAMPLED_SEARCH
        search = min(a * self.budget, b + c * self.budget)
        small = not self.collocates() or self.budget - search < MIN_COLLOCATION
        if small:
            search = SAMPLED_SMALL * self.budget
        if index:
            search = min(search, 0.5 * max(self.left(), 0.0))
        path, grown = self.connect(index, search)
        self.connected = path is not None
        if path is None:
            self.attempts.append(f"sampled plan: RRT-Connect found no connection after "
                                 f"{grown} nodes in {search:.3f} s")  # fmt: skip
            if index or (plan := exact_line(self)) is None:
                return None
            self.sampled_path = self.first_path = np.array([self.q0, self.q1])  # polish seed
            return plan
        how = "the straight line" if len(path) == 2 else f"RRT-Connect's path ({grown} nodes)"
        left = max(self.left(), 0.0)  # the exact check needs its share of it
        budget = SAMPLED_CHECK_SHARE * left if small else min(
            SAMPLED_RELAX * self.budget, SAMPLED_RELAX_MAX, SAMPLED_CHECK_SHARE * left)  # fmt: skip
        self.sampled_path, rough = pull_taut(self.p, path, budget, self.seed)
        plan = self.verified(self.sampled_path, f"{how} pulled taut in the metric")
        if plan is None and self.exact_failed:  # it cut a corner of the exact geometry
            self.sampled_path = rough
            plan = self.verified(rough, f"{how} shortened in the metric")
        self.first_path = self.sampled_path
        return plan

    def retry(self, index: int) -> Plan | None:
        """`sampled` from RRT-Connect seed ``seed + index`` after one that failed its checks:
        first, where it self-collided, its pair's floor raised near there
        (`Sampling.learn_floor`); if a raised floor left no connection, the calibrated
        floors back for the rest of the query. Said in the attempts."""
        raised = None
        if self.contact is not None and self.learning:
            raised, line = self.p.sampling.learn_floor(self.contact)
            self.attempts.append(line)
            self.contact = None  # learned from once
        quick = self.sampled(index)
        if raised is not None and not self.connected:
            self.p.sampling.forget_floors()
            self.learning = False
            self.attempts.append("self floors as calibrated: the raised one left no connection")
        return quick

    def polish(self, plan: Plan, budget: float = math.inf) -> Plan:
        """``plan`` (sampled) improved in the time left: seeds pulled taut on the covering
        spheres and tightened on the exact geometry
        (`geosyn.metrics.planning.polish.sphere_polish`), then seeds on a thinner sphere
        model pushed out on the exact geometry
        (`geosyn.metrics.planning.thin.thinner_plan`); with less than `THIN_FIRST` left,
        the thinner model first and the covering spheres only when it found nothing
        shorter. All within ``budget`` [s] when less than the time left."""
        end = time.perf_counter() + budget

        def left() -> float:
            return min(self.left(), end - time.perf_counter())

        if exact_movable(self.p) and left() < THIN_FIRST:
            if (thinner := thinner_plan(self, plan, left)) is not plan:
                return thinner
            return sphere_polish(self, plan, left)
        return thinner_plan(self, sphere_polish(self, plan, left), left)

    def ample(self, left: float) -> bool:
        """Whether a polishing with ``left`` [s] keeps `EXACT_KEEP` back for its exact
        tightening (more than twice that beyond two final checks)."""
        return left - 2.0 * self.reserve() > 2.0 * EXACT_KEEP

    def verified(self, path: np.ndarray, how: str, resample: bool = True) -> Plan | None:
        """The sampled plan of ``path`` (T, n) [rad] (``resample``: ``nodes + 1`` samples
        even in the metric, else its own) if it passes the checks (the exact one
        decides), else None; ``how`` it was made goes to its attempts and message."""
        p, t = self.p, time.perf_counter()
        if t > self.t0 + ANYTIME_SLACK * self.budget:  # an unchecked path is not returned
            self.attempts.append(f"sampled plan: {how}: no time left to check it")
            return None
        path = even_in_metric(p.metric, path, p.nodes + 1) if resample else path
        if why := outside_limits(p.robot, path):
            self.attempts.append(f"sampled plan: {how} leaves the joint limits ({why})")
            return None
        coarse, fine = p.check(path, smooth=False, fine=p.exact is None or p.given_spheres)
        exact = exact_check(p.exact, path, p.term.obstacles, p.exact_resolution,
                            self.t0 + ANYTIME_SLACK * self.budget, p.sampling.aids)  # fmt: skip
        ok = self.decide(exact, float(np.nanmin([coarse, fine])))[0] >= 0.0
        self.exact_failed = bool(exact.clearance < 0.0)  # not NaN: decided, and crossed
        own, self.contact = (p.self_contact(path, self.t0 + ANYTIME_SLACK * self.budget)
                             if ok else (math.nan, None))  # fmt: skip
        self.self_collided |= self.contact is not None
        self.check_time = time.perf_counter() - t
        if not ok or not p.self_ok(own):
            self.attempts.append(f"sampled plan: {how} fails the checks (exact clearance "
                                 f"{exact.clearance:.4f} m, spheres {min(coarse, fine):.4f} m, "
                                 f"self-clearance {own:.4f} m)")  # fmt: skip
            return None
        wall = time.perf_counter() - self.t0
        self.first = wall if math.isnan(self.first) else self.first
        self.attempts.append(f"sampled plan: {how}, verified at {wall:.3f} s")
        return Plan(feasible_result(p.metric, path, how), "sampled", coarse, wall,
                    tuple(self.attempts), fine, exact.clearance, p.exact_resolution,
                    self.first, self_clearance=own)  # fmt: skip

    def from_rrt(self, index: int, cap: float = math.inf) -> Plan | None:
        """Collocation from an RRT-Connect seed (``seed + index``; seed 0's path from
        `sampled` when it found one), or None; the sampling takes at most ``cap`` [s],
        the collocation at most twice that."""
        p, q0, q1 = self.p, self.q0, self.q1
        name = "RRT-Connect" if index == 0 else f"RRT-Connect #{index}"
        if index == 0 and self.first_path is not None and len(self.first_path) > 2:
            path = self.first_path  # its way round (the polished plan's may be another)
            self.attempts.append(f"{name}: the sampled plan's path as the seed")
        else:
            found, grown = self.connect(index, min(0.6 * self.left(), cap))
            if found is None:
                self.attempts.append(f"{name}: no connection after {grown} nodes")
                return None
            if len(found) == 2:  # the straight line is free: collocation already had it
                self.attempts.append(f"{name}: the straight line is collision-free")
                return None
            path = shortcut(
                p.sampling.valid,
                found,
                budget=0.05 * self.left(),
                seed=self.seed + index,
                segment=p.sampling.segment_valid,
            )
            self.attempts.append(f"{name}: path of {len(path)} vertices ({grown} nodes)")
        if (remaining := self.left()) <= 0:
            return None
        res = p.solve(p.collocation(p.nodes), q0, q1, init=path, budget=min(remaining, 2 * cap))
        self.attempts.append(f"collocation from the {name} path: {res.message}")
        if not res.success:
            self.unfinished.extend([(res.nodes, f"the interrupted collocation from the {name} "
                                    "path"), (path, f"the {name} path")])  # fmt: skip
            return None
        return self.finish(res, path, name.lower(), 1.0)

    def straight_line(self) -> Plan | None:
        """The plan from the straight line (through the coarse collocation among
        obstacles, else directly), or None."""
        p, q0, q1 = self.p, self.q0, self.q1
        if p.coarse_nodes and p.term.obstacles:
            share = COARSE_TO_FINE * max(self.left(), 1e-3)
            res, init = coarse_to_fine(p, q0, q1, share, self.attempts)
            if not res.success:
                self.unfinished += [
                    (res.nodes, "the interrupted collocation from the coarse path"),
                    (init, "the coarse collocation's path"),
                ]
                if res.status == "User_Requested_Stop":  # the clock: a colder start
                    self.attempts.append("collocation from the straight line skipped: the "
                                         "one from the coarse path ran out of its time")  # fmt: skip
                    return None
            elif (plan := self.finish(res, init, "straight line", 0.9)) is not None:
                return plan
        res = p.solve(p.collocation(p.nodes), q0, q1, budget=max(0.5 * self.left(), 1e-3))
        self.attempts.append(f"collocation from the straight line: {res.message}")
        if not res.success:
            self.unfinished.append((res.nodes, "the interrupted collocation from the line"))
            return None
        return self.finish(res, None, "straight line", 0.75)

    def keep(self, line: Plan | None, others: list[Plan]) -> Plan:
        """`geosyn.metrics.planning.homotopy.kept_plan` of ``line`` (the straight line's,
        if any) and ``others``, with this query's wall time, attempts and first time."""
        best = kept_plan(self.p.metric, line, others, self.attempts)
        first = self.first if not math.isnan(self.first) else best.first_feasible_time
        return best._replace(wall_time=time.perf_counter() - self.t0,
                             attempts=tuple(self.attempts), first_feasible_time=first)  # fmt: skip

    def collocates(self) -> bool:
        """`Planner.collocates` for this query's obstacles. Where it does not, the sampled
        plan tightened on the meshes came within 0.6 % of the same length on the 14 Panda
        benchmark scenes at 5 s, returning after 0.6-3.8 s instead of 0.5-5.9 s
        (`benchmarks/RESULTS.md`, issue 22, fifteenth round)."""
        return self.p.collocates(len(self.p.term.obstacles))

    def run(self) -> Plan:
        """The plan (see the module docstring), or `NoPathFound` once the budget is spent."""
        quick, took, index = self.sampled(), time.perf_counter() - self.t0, 0
        while (  # after a self-collision until the time is spent (the NLP has no term for
            quick is None  # it), else at most SAMPLED_RETRIES while no collocation would run
            and self.left() > took
            and (
                self.self_collided
                or (
                    index < SAMPLED_RETRIES
                    and not (self.collocates() and self.left() > MIN_COLLOCATION)
                )
            )
        ):
            index += 1
            quick = self.retry(index)
        others: list[Plan] = [quick] if quick is not None else []
        meshes = quick is not None and not self.collocates()  # else: as a fallback
        if meshes or self.left() <= MIN_COLLOCATION:
            self.attempts.append(
                "collocation not started: the sampled plan is tightened on the robot's own "
                "geometry" if meshes else f"collocation not started: "
                f"{max(self.left(), 0.0):.3f} s left, less than {MIN_COLLOCATION:g} s"
            )  # fmt: skip
            if quick is None:
                raise self.refusal()
            return self.keep(None, [self.polish(quick)])
        if quick is not None:  # first as with a smaller budget, then the collocations
            others = [self.polish(quick, min(POLISH_FIRST * self.budget, POLISH_FIRST_MAX))]
        line = self.straight_line()
        if line is None:
            if self.left() <= 0:
                self.attempts.append("no time left for RRT-Connect seed 0")
            elif (plan := self.from_rrt(0)) is not None:
                others.append(plan)
        elif line.result.kind == "constrained":
            others += alternative_plans(self, line)
        if line is None and not others and self.unfinished:  # anytime: the lowest-energy
            end = self.t0 + ANYTIME_SLACK * self.budget  # path that passes the checks
            plan = anytime_plan(self.p, self.unfinished, self.t0, self.attempts, end, self.decide)
            others += [plan] if plan is not None else []
        if line is not None or others:
            best = self.keep(line, others)
            return self.keep(None, [self.polish(best)]) if best.seed == "sampled" else best
        raise self.refusal()

    def refusal(self) -> NoPathFound:
        """`NoPathFound` listing what was tried."""
        return NoPathFound.after(self.budget, time.perf_counter() - self.t0, tuple(self.attempts))
