"""`Sampling`: a planner's checks for sampling-based search, on its collision spheres.

What RRT-Connect, string pulling, shortcuts and the relaxation of a path ask many times
a query: is a configuration, a joint segment valid (sphere clearance to the query's
obstacles at least the sampling margin, no self pair below its floor), and the search
itself (`connect`). In C wherever the robot's joints allow
(`geosyn.metrics.planning.sphere_native`, about 1 us a configuration on the Panda), else
in numpy (`geosyn.metrics.planning.sphere_check`, said once).

A query sets its obstacles and ends (`start`): near each end the self pairs' floors
ramp down to the end's own sphere distances (`SELF_FLOOR_RAMP`) and the sampling margin
to the end's own clearance (`SAMPLING_RAMP`): the spheres reach beyond the links, so an end
clear of the exact geometry may sit nearer on the spheres; where an end has no way out
of those ramps (`Sampling.shut_in`), the self floors' ramp is halved for the query
(`SELF_RAMP_HALVINGS`). A self pair whose spheres
overlap on much of the joint box (`SELF_CALIBRATE`) has its floor calibrated on the
file's own geometry (`calibrated_slack`): lowered to just above the least overlap of its
spheres at which coal found the links touching at seeded configurations; on most of it
(`SELF_UNINFORMATIVE`), by the two links' reach beyond their convex hulls (the spheres
cannot tell). On a UR10 a floor at 0 for the first kind blocked much of the joint box
where the links are apart (they are 1-2 cm apart where their spheres overlap), and
seeded random queries were planned 1 in 8.
RRT-Connect (`connect`) draws `NEAR_SHARE` of its samples from the box round the
query's ends (`near_box`), the rest from the whole sampling box: first paths that keep
near start and goal where such a way exists (fewer long ways round), a connection
wherever the whole box has one.
The exact check decides every returned plan,
self-collision included. Where it finds a path the spheres passed intersecting itself
(a calibrated or uninformative floor let it through), the query raises that pair's floor
above the spheres' distance there, within `SELF_LEARN_RADIUS` of that configuration, for
its remaining search (`Sampling.learn_floor`): lazy collision checking, the exact
geometry correcting the spheres where they were wrong, so that the next search does not
return the same path, while the pair may come as near elsewhere (where its links are
apart at that overlap).
For a robot with a file, the file's fitted spheres also
give the exact check its aids (`aids`: joint placements in C and lower bounds of every
(collision object, obstacle) distance from the spheres that cover the object's link).
"""

from __future__ import annotations

import functools
import hashlib
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from geosyn.core.cache_folder import read_json, store_json
from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_float
from geosyn.metrics.planning.exact_path import PathAids
from geosyn.metrics.planning.rrt import RRT_STEP, Near, rrt_connect
from geosyn.metrics.planning.self_collision import SelfCollision
from geosyn.metrics.planning.self_path import SelfContact
from geosyn.metrics.planning.sphere_check import Raises, SphereCheck
from geosyn.metrics.planning.sphere_native import NativeSphereCheck, sphere_check
from geosyn.robots.robot import CollisionSphere, Robot
from geosyn.world.exact_clearance import ExactClearance
from geosyn.world.shapes import Shape

if TYPE_CHECKING:
    from geosyn.robots.collision_spheres import SphereModel

__all__ = [
    "SAMPLING_RAMP",
    "SAMPLING_SLACK",
    "SELF_CALIBRATE",
    "SELF_CALIBRATION_ITEMS",
    "SELF_CALIBRATION_SAFETY",
    "SELF_FLOOR_RAMP",
    "SELF_LEARN_RADIUS",
    "SELF_LEARN_STEP",
    "SELF_RAMP_HALVINGS",
    "SELF_SAMPLES",
    "SELF_UNINFORMATIVE",
    "CALIBRATION_VERSION",
    "ESCAPE_PROBES",
    "ESCAPE_RESOLUTION",
    "NEAR_REACH",
    "NEAR_SHARE",
    "Sampling",
    "cached_slack",
    "calibrated_slack",
    "near_box",
    "sampling_box",
]

SAMPLING_SLACK = 1e-6
"""[m] below an end's sphere clearance: the margin in force at that end."""

SAMPLING_RAMP = 0.05
"""Slope [m/rad] of the margin near a query's ends: from an end's own sphere clearance
(when below the margin) back up to the margin within ``(margin - c) / slope`` rad
(0.1 rad from an end touching its spheres, for the default 5 mm), as the collocation's
clearance bounds ramp from its ends."""

NEAR_REACH = 0.5
"""Reach [rad] of `near_box` beyond the box spanned by a query's start and goal, per
joint. On the 14 Panda benchmark scenes (8 query seeds, budgets 0.05 / 0.1 / 0.2 s, both
in one process by turns), 0.3 gave paths 3.0 / 1.6 / 0.6 % longer than 0.5 (geometric
mean of the length ratios), 0.8 1.4 / 0.0 / 0.5 % longer (measured)."""

NEAR_SHARE = 0.5
"""Share of RRT-Connect's samples drawn from `near_box` (`Sampling.connect`). On the same
scenes and seeds, against none (all from the whole box): paths 8.5 / 2.7 / 2.4 % shorter
at 0.05 / 0.1 / 0.2 s (shelf_compartments 31 %, shelf 13 %, low_bar 5 % longer); 0.75
about the same as 0.5. Every sample there: no first path round the pillar scene, whose
way lies outside the box (measured)."""

SELF_FLOOR_RAMP = 0.05
"""Slope [m/rad] of a self pair's floor near a query's ends: from an end's own sphere
distance (when below the pair's floor) back up to that floor within ``(floor - d) /
slope`` rad. Lowered everywhere (as before the sixteenth round), the goal's 69 mm overlap
of a Panda's hand and base spheres let a path touch them 3.1 rad away (seeded random
query 5 of `benchmarks/planning_random.py`)."""

SELF_RAMP_HALVINGS = 4
"""Most halvings of `SELF_FLOOR_RAMP` for a query one of whose ends has no way out on
the self floors: no segment of `RRT_STEP` from it valid for the self pairs in any of
`ESCAPE_PROBES` seeded directions (`Sampling.start`, said in the attempts). A UR5 with
its gripper had such an end (forearm / tool0 spheres 13.5 mm into each other, the links
apart): valid in 13.7 % of directions for 0.1 rad and none for 0.2 rad, so RRT-Connect
grew 3 nodes in 1.6 s; at 0.025 m/rad it found a path, 6.9 mm clear of itself on the
meshes (measured). The exact check decides the path either way. Of 96 seeded random
queries per robot (`benchmarks/planning_random.py`, seeds 0-11), only the UR3 had ends
still shut in after two halvings (3 queries): at most two, 2 of their 6 plans (two plan
seeds each) within the default 5 s; at most four, 6 of 6 (three halvings sufficed,
measured)."""

ESCAPE_PROBES = 64
"""Seeded directions in which `Sampling.start` looks for a way out of each end."""

ESCAPE_RESOLUTION = 0.05
"""Check step [rad] of those segments (RRT-Connect's edge resolution)."""

SELF_CALIBRATE = 0.2
"""Share of seeded configurations in the joint box (`SELF_SAMPLES` of them) at which a
self pair's spheres overlap, above which `calibrated_slack` calibrates the pair's floor
on the meshes (UR5 and UR10: two pairs each at 32-41 %; no Panda, xArm7 or Kinova Gen2
pair above 15 %)."""

SELF_UNINFORMATIVE = 0.5
"""That share above which the pair's sphere distance is taken to say nothing (the UR5's
base and upper arm: 100 %, its wrist 1 and 3: 84 %): its floor goes down by the two
links' reach beyond their convex hulls. Calibrating these too (the UR5's base and upper
arm touch from 39 mm of overlap, and are apart up to 56 mm) planned 14 of 24 seeded
random queries on a UR5 with its gripper against 17 (`benchmarks/RESULTS.md`, issue 22,
sixteenth round)."""

SELF_LEARN_STEP = 0.005
"""[m] above a self pair's sphere distance at a configuration where the exact check found
its links intersecting, to which `Sampling.learn_floor` raises the pair's floor for the
rest of the query. A calibrated slack comes from `SELF_SAMPLES` configurations: the links
may touch at a shallower overlap elsewhere."""

SELF_LEARN_RADIUS = 4.0
"""Radius [rad] (joint-space 2-norm) round a configuration where the exact check found a
self pair's links intersecting within which `Sampling.learn_floor` raises that pair's
floor. Raised everywhere instead (as in the twentieth round), a floor that blocked the
way left no connection, and the retries returned paths crossing the same links; seeded
random UR5 queries, 2 s each (`benchmarks/planning_random.py`, seeds 0-5 / 6-11, 48
queries each, alternating in one process): everywhere 32 / 28 planned; 2 rad 41-42 / -,
3 rad 40 / 44, 4 rad 45-46 / 41, 5 rad - / 40, 6 rad 42 / - (measured)."""

SELF_SAMPLES = 1000
"""Configurations drawn (seed 0) to find the pairs `SELF_CALIBRATE` calibrates."""

SELF_CALIBRATION_ITEMS = 1000
"""Most of those configurations, per calibrated pair, at which coal measures the links
(where the pair's spheres overlap, the least overlap first, until the links touch)."""

SELF_CALIBRATION_SAFETY = 0.002
"""[m] kept back from the calibrated slack: the least overlap at which the links touched
among the seeded configurations may be a little more than over the whole joint box."""


def calibrated_slack(check: SphereCheck, links: Sequence[str],
                     reach: Sequence[float]) -> np.ndarray:  # fmt: skip
    """(P,) per self pair of ``check`` [m]: how far below 0 its floor (`SphereCheck.
    set_ends`) may go in the sampled search, from `SELF_SAMPLES` seeded
    configurations in the joint box (infinite limits: +-pi) and the two links' ``reach``
    beyond their convex hulls (``links``' order of first appearance,
    `SphereModel.reach`). A pair whose spheres overlap on more than `SELF_UNINFORMATIVE`
    of them: that reach (the spheres cannot tell). On more than `SELF_CALIBRATE`: coal
    measures the links (`SelfCollision`, built only then) where the spheres overlap, the
    least overlap first, up to `SELF_CALIBRATION_ITEMS` configurations: the overlap at
    which they first touch, less `SELF_CALIBRATION_SAFETY` (none touched: the reach), at
    most the reach. Else 0."""
    if not check.self_pairs:
        return np.zeros(0)
    model = check.robot.model
    lo = np.where(np.isfinite(check.robot.q_min), check.robot.q_min, -np.pi)
    hi = np.where(np.isfinite(check.robot.q_max), check.robot.q_max, np.pi)
    Q = np.random.default_rng(0).uniform(lo, hi, size=(SELF_SAMPLES, model.nq))
    spheres = check.self_clearances(Q)
    of = dict(zip(dict.fromkeys(links), reach, strict=True))
    slack = np.zeros(len(check.self_pairs))
    exact: SelfCollision | None = None
    share = np.mean(spheres < 0.0, axis=0)
    for k in np.flatnonzero(share > SELF_CALIBRATE):
        a, b = pair = check.self_pairs[k]
        slack[k] = cap = of[a] + of[b]
        if share[k] > SELF_UNINFORMATIVE:
            continue  # the spheres cannot tell
        exact = exact or SelfCollision(check.robot, check.self_pairs)
        at = np.flatnonzero(spheres[:, k] < 0.0)
        at = at[np.argsort(-spheres[at, k], kind="stable")]  # the least overlap first
        for i in at[:SELF_CALIBRATION_ITEMS]:
            if exact.clearance(Q[i], pair)[0] < 0.0:  # the first touch: the least overlap
                slack[k] = min(max(-spheres[i, k] - SELF_CALIBRATION_SAFETY, 0.0), cap)
                break
    return slack


CALIBRATION_VERSION = 2
"""Part of `cached_slack`'s disk cache key: bumped when the calibration changes."""


def cached_slack(check: SphereCheck, fitted: SphereModel) -> np.ndarray:
    """`calibrated_slack` of ``check`` (its self pairs set from ``fitted``, the file's
    sphere model), kept on disk beside the fitted spheres (``slack_<hash>.json`` in
    `geosyn.robots.collision_spheres.sphere_cache_dir`, keyed by the model, the pairs, the
    joint limits and the calibration's constants): a warm process reads it back instead
    of measuring again (0.24-0.44 s on the UR arms, 2.3 s on the SO-101, measured). A
    damaged entry is measured again, warned."""
    from geosyn.robots.collision_spheres import sphere_cache_dir

    rows = [(s.joint, tuple(map(float, s.center)), float(s.radius)) for s in fitted.spheres]
    robot = check.robot
    key = (f"{fitted.digest}|{rows!r}|{check.self_pairs!r}|{robot.q_min.tolist()!r}|"
           f"{robot.q_max.tolist()!r}|{SELF_SAMPLES}|{SELF_CALIBRATE!r}|"
           f"{SELF_CALIBRATION_ITEMS}|{SELF_CALIBRATION_SAFETY!r}|{SELF_UNINFORMATIVE!r}|"
           f"{CALIBRATION_VERSION}")  # fmt: skip
    path = sphere_cache_dir() / f"slack_{hashlib.sha256(key.encode()).hexdigest()[:24]}.json"

    def parse(data: Any) -> np.ndarray:
        found = np.array(data["slack"], dtype=float)
        if found.shape == (len(check.self_pairs),) and np.all(np.isfinite(found)):
            return found
        raise ValueError(f"shape {found.shape} for {len(check.self_pairs)} finite values")

    if (found := read_json(path, parse, "sphere cache", "measuring again")) is not None:
        return found
    slack = calibrated_slack(check, fitted.links, fitted.reach)
    store_json(path, {"slack": slack.tolist()}, "the sphere cache", 2)
    return slack


@functools.cache
def _directions(n: int) -> np.ndarray:
    """(`ESCAPE_PROBES`, n) seeded unit vectors (`Sampling.shut_in`)."""
    u = np.random.default_rng(0).standard_normal((ESCAPE_PROBES, n))
    return u / np.linalg.norm(u, axis=1)[:, None]


def near_box(lo: np.ndarray, hi: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> Near:
    """(lo (n,), hi (n,), `NEAR_SHARE`): the box [rad] spanned by ``q0`` and ``q1`` (n,)
    widened by `NEAR_REACH` per joint, within the sampling box ``[lo, hi]`` (n,) [rad]
    (`sampling_box`), and the share of RRT-Connect's samples drawn from it."""
    near_lo = np.maximum(lo, np.minimum(q0, q1) - NEAR_REACH)
    near_hi = np.minimum(hi, np.maximum(q0, q1) + NEAR_REACH)
    return near_lo, np.maximum(near_hi, near_lo), NEAR_SHARE


def sampling_box(robot: Robot, q0: np.ndarray, q1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """((n,), (n,)) the box [rad] a query's RRT-Connect samples from ``q0`` to ``q1`` (n,):
    the joint limits, or within pi of start and goal where they are infinite."""
    lo = np.maximum(robot.q_min, np.minimum(q0, q1) - np.pi)
    hi = np.minimum(robot.q_max, np.maximum(q0, q1) + np.pi)
    return lo, hi


class Sampling:
    """The sampling checks of one planner (module docstring).

    Args:
        robot: the robot.
        spheres: the planner's collision spheres (those its constraints use).
        exact: the exact checker of the robot's file geometry, or None (no file): then
            no self pairs and no aids.
        margin: the sampling margin outside a query [m] (the planner's margin / 2).

    Attributes:
        check: the sphere check (`NativeSphereCheck` or `SphereCheck`).
        note: why the check is in numpy ("" when in C).
        margin: the sampling margin [m] (lower near a query's ends: `start`).
        aids: the exact check's aids (`PathAids`; empty without a file or without C).
    """

    def __init__(self, robot: Robot, spheres: Sequence[CollisionSphere],
                 exact: ExactClearance | None, margin: float) -> None:  # fmt: skip
        self.robot, self.exact = robot, exact
        self.check: SphereCheck
        self.check, self.note = sphere_check(robot, spheres)
        self.margin = margin
        self.ramp = SELF_FLOOR_RAMP  # a query's (`start`)
        self._obstacles: tuple[Shape, ...] = ()
        self._cover: NativeSphereCheck | None = None
        self._cover_group = np.zeros(0, dtype=np.int32)  # each fitted sphere's link
        self._object_link = np.zeros(0, dtype=int)  # each file collision object's link
        self._covered = np.zeros(0, dtype=int)  # the objects whose link has fitted spheres
        self.aids = PathAids()
        if exact is None:
            return
        from geosyn.robots.collision_spheres import file_spheres  # cached on disk

        fitted = file_spheres(robot)
        self.check.set_self_pairs(fitted.spheres, fitted.links, fitted.self_pairs)
        self.check.self_slack = cached_slack(self.check, fitted)
        if isinstance(self.check, NativeSphereCheck):
            self._cover = NativeSphereCheck(robot, fitted.spheres)
            links = sorted({o.link for o in exact.objects})
            group = [links.index(link) if link in links else -1 for link in fitted.links]
            self._cover_group = np.array(group, dtype=np.int32)
            self._object_link = np.array([links.index(o.link) for o in exact.objects], dtype=int)
            self._covered = np.flatnonzero(np.isin(self._object_link, self._cover_group))
            self.aids = PathAids(self.exact_bounds, self._cover.joint_frames)

    def start(self, obstacles: Sequence[Shape], q0: np.ndarray, q1: np.ndarray) -> None:
        """A query's obstacles and ends (n,) [rad]: self floors lowered to the ends'
        sphere distances near them, the sampling margin ramped down to theirs (module
        docstring); the self floors' ramp (``ramp`` [m/rad]) halved while an end is
        `shut_in`, at most `SELF_RAMP_HALVINGS` times (``ramp_line`` says so). A halving
        lowers the floors near the ends, so an end with a way out keeps it: only the ends
        still shut in are probed again."""
        self._obstacles = tuple(obstacles)
        self.check.set_obstacles(self._obstacles)
        ends = np.minimum(self.check.clearances(np.array([q0, q1])) - SAMPLING_SLACK,
                          self.margin)  # fmt: skip
        self.ramp = SELF_FLOOR_RAMP
        self.check.set_ends([q0, q1], ends, SAMPLING_RAMP, self.ramp)
        if not self.check.self_pairs:
            return
        shut = [q for q in (q0, q1) if self.shut_in(q)]
        for _ in range(SELF_RAMP_HALVINGS):
            if not shut:
                break
            self.ramp *= 0.5
            self.check.set_ends([q0, q1], ends, SAMPLING_RAMP, self.ramp)
            shut = [q for q in shut if self.shut_in(q)]

    @property
    def ramp_line(self) -> str:
        """What the query's eased self ramp is, for its attempts ("" when not eased)."""
        if self.ramp >= SELF_FLOOR_RAMP:
            return ""
        return (
            f"self floors ramp up at {self.ramp:g} m/rad near the ends, not "
            f"{SELF_FLOOR_RAMP:g}: an end had no way out of them"
        )

    def shut_in(self, q: np.ndarray) -> bool:
        """Whether no segment of `RRT_STEP` [rad] from ``q`` (n,) [rad] is valid for the
        self pairs (the obstacles left out) in any of `ESCAPE_PROBES` seeded directions,
        clipped to the joint limits."""
        ends = np.clip(q + RRT_STEP * _directions(len(q)), self.robot.q_min, self.robot.q_max)
        return not any(self.check.segment_valid(q, e, ESCAPE_RESOLUTION, -math.inf) for e in ends)

    def learn_floor(self, contact: SelfContact,
                    radius: float = SELF_LEARN_RADIUS) -> tuple[float | None, str]:  # fmt: skip
        """For the rest of the query (`start`), raise the floor of the self pair of
        ``contact`` (where the exact check found its links intersecting on a path the
        spheres passed) within ``radius`` [rad] of it (joint-space 2-norm; inf:
        everywhere) to `SELF_LEARN_STEP` above the pair's sphere distance there, so that
        the search no longer passes that configuration (module docstring). Never above
        the pair's sphere distance at an end within ``radius`` (the floors ramp up from
        there, `SELF_FLOOR_RAMP`: the end would be shut in): capped there, and not raised
        when the cap is not above the pair's distance at the contact. Not either when the
        floor in force there is already as high (the path passed between the checked
        samples, or near an end). Returns the new floor [m] (or None) and a sentence
        saying what was done.
        """
        ends = self.check.ends  # the query's, with their pair distances (`start`)
        if not len(ends.E):
            raise InvalidArgument("learn_floor: only within a query (after start)")
        if radius != math.inf:  # inf: everywhere
            radius = check_float(radius, "radius", low=0.0, unit="rad")
        k = int(contact.pair)
        a, b = self.check.self_pairs[k]
        d = float(self.check.self_clearances(contact.q)[0, k])
        near = np.linalg.norm(ends.E - contact.q, axis=1) < radius
        cap = float(ends.D[near, k].min(initial=math.inf))  # an end within the radius
        floor = min(d + SELF_LEARN_STEP, cap)
        if floor <= d:
            return None, (f"self pair {a}/{b}: floor not raised (an end within {radius:g} "
                          "rad is as near on the spheres: it would shut that end in)")  # fmt: skip
        if floor <= float(self.check.self_floors(contact.q)[0, k]):
            return None, f"self pair {a}/{b}: floor not raised (already as high there)"
        r = self.check.raises
        self.check.set_raises(Raises(np.append(r.pair, k), np.vstack([r.at, contact.q]),
                                     np.append(r.radius, radius), np.append(r.floor, floor)))  # fmt: skip
        return floor, (f"self pair {a}/{b}: floor raised to {floor:.4f} m within {radius:g} "
                       f"rad of where the links intersect (their spheres {d:.4f} m apart) "
                       "for this query")  # fmt: skip

    def forget_floors(self) -> None:
        """The calibrated floors back for the rest of the query (`learn_floor`'s raises
        dropped)."""
        if len(self.check.raises.pair):
            self.check.set_raises(Raises.none(self.robot.model.nq))

    def finish(self) -> None:
        """End of a query: no ends (the sampling margin and the self floors away from any
        ends, everywhere), the calibrated floors back (`learn_floor`)."""
        self.forget_floors()
        self.check.set_ends([], [], 0.0)
        self.ramp = SELF_FLOOR_RAMP

    def set_obstacles(self, obstacles: Sequence[Shape]) -> None:
        """The obstacles the checks use (`start` sets them for a query)."""
        self._obstacles = tuple(obstacles)
        self.check.set_obstacles(self._obstacles)

    def valid(self, Q: np.ndarray) -> np.ndarray:
        """(K,) True where the configurations ``Q`` (K, n) [rad] keep sphere clearance >=
        ``margin`` to the obstacles and no self pair is below its floor."""
        return self.check.valid(Q, self.margin)

    def segment_valid(self, a: np.ndarray, b: np.ndarray, resolution: float) -> bool:
        """Whether the joint segment ``a`` -> ``b`` (n,) [rad] is valid (`valid`) every
        ``resolution`` [rad] (2-norm; ``a`` itself not checked), stopping at the first
        invalid configuration."""
        return self.check.segment_valid(a, b, resolution, self.margin)

    def connect(self, q0: np.ndarray, q1: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                budget: float, seed: int) -> tuple[np.ndarray | None, int]:  # fmt: skip
        """RRT-Connect from ``q0`` to ``q1`` (n,) [rad] in the box ``[lo, hi]`` within
        ``budget`` [s] on `valid` (`geosyn.metrics.planning.rrt.rrt_connect`'s result),
        `NEAR_SHARE` of its samples from `near_box`: in C with the native check, else in
        Python."""
        near = near_box(lo, hi, q0, q1)
        if isinstance(self.check, NativeSphereCheck):
            return self.check.rrt_connect(q0, q1, lo, hi, margin=self.margin, budget=budget,
                                          seed=seed, near=near)  # fmt: skip
        return rrt_connect(self.valid, q0, q1, lo, hi, budget=budget, seed=seed, near=near)

    def exact_bounds(self, Q: np.ndarray) -> np.ndarray:
        """(K, L, O) lower bounds [m] of the exact distance of each collision object of
        the file (L, `ExactClearance.objects`) to each obstacle (O) at the configurations
        ``Q`` (K, n) [rad]: the smallest clearance of the fitted spheres of its link (they
        cover every point of the link's geometry, so no point is nearer; ``-inf`` for a
        link without spheres)."""
        Q = np.asarray(Q, dtype=float).reshape(-1, self.robot.model.nq)
        out = np.full((len(Q), len(self._object_link), len(self._obstacles)), -math.inf)
        if self._cover is None or not self._obstacles or not self._covered.size:
            return out
        self._cover.set_obstacles(self._obstacles)
        count = int(self._object_link.max()) + 1
        per_link = self._cover.group_distances(Q, self._cover_group, count)  # (K, links, O)
        out[:, self._covered] = per_link[:, self._object_link[self._covered]]
        return out
