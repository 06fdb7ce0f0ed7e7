"""ObstacleTerm: distances, the pulled-back barrier, parameters without rebuilds, errors."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from conftest import get_metric, get_robot
from geosyn.metrics.shaping import CapacityExceeded, InvalidTermArgument, ObstacleTerm, ShapedMetric
from geosyn.metrics.shaping.obstacle import HOMOTOPY_RADIUS, PARAMS_PER_OBSTACLE
from geosyn.world import Box, Capsule, HalfSpace, InvalidGeometry, Sphere

# -- numpy reference ------------------------------------------------------------------


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    return pin.exp3(np.asarray(axis, dtype=float) / np.linalg.norm(axis) * angle)


def _sd_numpy(ob, x: np.ndarray) -> float:
    """Exact signed distance of a point to an obstacle, written independently."""
    if isinstance(ob, Sphere):
        return float(np.linalg.norm(x - ob.center) - ob.radius)
    if isinstance(ob, Capsule):
        a, b = np.asarray(ob.p0), np.asarray(ob.p1)
        t = np.clip(np.dot(x - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
        return float(np.linalg.norm(x - (a + t * (b - a))) - ob.radius)
    if isinstance(ob, HalfSpace):
        return float(np.dot(ob.normal, x) - ob.offset)
    R = np.asarray(ob.rotation)
    p = np.abs(R.T @ (x - np.asarray(ob.center))) - np.asarray(ob.half_extents)
    return float(np.linalg.norm(np.maximum(p, 0.0)) + min(p.max(), 0.0))


def _sd_grad_numpy(ob, x: np.ndarray, h: float = 1e-7) -> np.ndarray:
    return np.array(
        [(_sd_numpy(ob, x + h * e) - _sd_numpy(ob, x - h * e)) / (2 * h) for e in np.eye(3)]
    )


def _sphere_kinematics(robot, q: np.ndarray):
    """World centres (3,) and point Jacobians (3, n) of the collision spheres, by Pinocchio."""
    model = robot.model
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    out = []
    for s in robot.collision_spheres():
        jid = model.getJointId(s.joint)
        oMi = data.oMi[jid]
        x = oMi.rotation @ np.asarray(s.center) + oMi.translation
        J = pin.getJointJacobian(model, data, jid, pin.LOCAL_WORLD_ALIGNED)
        Jp = J[:3] - pin.skew(x - oMi.translation) @ J[3:]
        out.append((x, Jp, s.radius))
    return out


def _reference_G(robot, q, obstacles, gain, cutoff, v=None, gate_speed=None) -> np.ndarray:
    n = robot.nv
    G = np.zeros((n, n))
    for x, Jp, r in _sphere_kinematics(robot, q):
        for ob in obstacles:
            d = _sd_numpy(ob, x) - r
            if d >= cutoff:
                continue
            w = gain * (1.0 / d - 1.0 / cutoff) ** 2
            g = Jp.T @ _sd_grad_numpy(ob, x)
            if gate_speed is not None:
                s = np.clip(-(g @ v) / gate_speed, 0.0, 1.0)
                w *= s * s * (3 - 2 * s)
            G += w * np.outer(g, g)
    return G


def _scene() -> list:
    return [
        Sphere((0.45, 0.15, 0.45), 0.08),
        Box((0.3, -0.35, 0.35), (0.05, 0.08, 0.1), _rot([1, 2, 3], 0.7)),
        Capsule((0.5, -0.2, 0.7), (0.55, 0.25, 0.75), 0.04),
        HalfSpace(np.array([0.1, 0.0, 1.0]) / np.linalg.norm([0.1, 0.0, 1.0]), 0.05),
    ]


def _random_clear_q(robot, term, rng, min_clear=0.01):
    while True:
        q = robot.random_q(rng)
        if term.min_clearance(q) > min_clear:
            return q


# -- tests ----------------------------------------------------------------------------


def test_clearances_match_exact_distances() -> None:
    robot = get_robot("panda")
    obstacles = _scene()
    term = ObstacleTerm(obstacles, capacity=5).bind(robot)
    rng = np.random.default_rng(20)
    for _ in range(20):
        q = robot.random_q(rng)
        ref = np.array(
            [[_sd_numpy(ob, x) - r for ob in obstacles] for x, _, r in _sphere_kinematics(robot, q)]
        )
        c = term.clearances(q)
        assert c.shape == (len(robot.collision_spheres()), 4)
        np.testing.assert_allclose(c, ref, atol=1e-12)


def test_term_equals_pulled_back_barrier_reference() -> None:
    robot = get_robot("panda")
    obstacles = _scene()
    gain, cutoff = 2e-3, 0.25
    term = ObstacleTerm(obstacles, capacity=6, gain=gain, cutoff=cutoff).bind(robot)
    rng = np.random.default_rng(21)
    active = 0
    for _ in range(15):
        q = _random_clear_q(robot, term, rng)
        ref = _reference_G(robot, q, obstacles, gain, cutoff)
        G = term.G(q)
        active += np.abs(ref).max() > 1e-6
        np.testing.assert_allclose(G, ref, rtol=1e-6, atol=1e-9 * max(1.0, np.abs(ref).max()))
    assert active >= 5


def test_weight_grows_without_bound_and_vanishes_beyond_cutoff() -> None:
    """On planar2, one sphere obstacle approached along a line: w ~ gain / d^2, 0 past cutoff."""
    robot = get_robot("planar2")
    metric = get_metric("planar2")
    term = ObstacleTerm([Sphere((2.0, 0.5, 0.0), 0.1)], capacity=1, gain=1e-3, cutoff=0.3)
    shaped = ShapedMetric(metric, [term])
    # q = 0: the tip sphere (centre (2, 0, 0), radius 0.02) moves along y, towards the
    # obstacle placed beside it.
    norms = []
    for gap in (0.2, 0.02, 0.002, 0.0002):
        term.move(0, (2.0, 0.1 + 0.02 + gap, 0.0))
        assert abs(term.min_clearance(np.zeros(2)) - gap) < 1e-12
        norms.append(np.abs(shaped.terms_G(np.array([0.0, 0.0]), None)).max())
    # ~1/gap^2 growth: factor ~100 per decade once gap << cutoff.
    assert norms[2] / norms[1] > 80 and norms[3] / norms[2] > 95
    term.move(0, (2.0, 0.5, 0.0))  # every sphere farther than the cutoff
    assert term.min_clearance(np.zeros(2)) > 0.3
    assert np.array_equal(shaped.terms_G(np.zeros(2)), np.zeros((2, 2)))
    assert not np.any(shaped.christoffel(np.zeros(2)) - metric.christoffel(np.zeros(2)) > 1e-12)
    assert robot.nv == 2


def test_approach_gate_only_when_approaching() -> None:
    robot = get_robot("panda")
    obstacles = _scene()[:2]
    gain, cutoff, speed = 2e-3, 0.3, 0.1
    term = ObstacleTerm(
        obstacles, capacity=2, gain=gain, cutoff=cutoff, gate="approach", gate_speed=speed
    ).bind(robot)
    assert term.velocity_dependent
    rng = np.random.default_rng(22)
    for _ in range(10):
        q = _random_clear_q(robot, term, rng)
        v = rng.normal(size=7)
        ref = _reference_G(robot, q, obstacles, gain, cutoff, v=v, gate_speed=speed)
        np.testing.assert_allclose(
            term.G(q, v), ref, rtol=1e-6, atol=1e-9 * max(1.0, np.abs(ref).max())
        )
        # At rest nothing approaches: the gated term is off.
        assert np.array_equal(term.G(q), np.zeros((7, 7)))


def test_rmp_profile_is_bounded() -> None:
    robot = get_robot("planar2")
    term = ObstacleTerm(
        [Sphere((2.0, 0.5, 0.0), 0.1)], capacity=1, profile="rmp", gain=1e-3, epsilon=0.1
    ).bind(robot)
    # Only the tip sphere (radius 0.02) is within the cutoff; for it
    # w <= gain / epsilon and |grad d| <= |J_tip| (n is a unit vector).
    _, Jp, _ = _sphere_kinematics(robot, np.zeros(2))[-1]
    bound = 1e-3 / 0.1 * np.linalg.norm(Jp, 2) ** 2
    top = []
    for gap in (0.05, 1e-3, 1e-6, -0.01):
        term.move(0, (2.0, 0.1 + 0.02 + gap, 0.0))
        top.append(np.linalg.eigvalsh(term.G(np.zeros(2)))[-1])
        assert top[-1] <= bound * (1 + 1e-12)
    # Bounded but approaching its bound near contact.
    assert top[2] > 0.9 * bound


def test_moving_and_adding_obstacles_rebuilds_nothing() -> None:
    robot = get_robot("panda")
    term = ObstacleTerm([Sphere((0.45, 0.15, 0.45), 0.08)], capacity=3, gain=2e-3, cutoff=0.3)
    shaped = ShapedMetric(get_metric("panda"), [term])
    rng = np.random.default_rng(23)
    q = robot.random_q(rng)
    shaped.G(q)
    shaped.christoffel(q)
    builds = (shaped.build_count, term.build_count)
    params_before = shaped.parameter_values().copy()
    for k in range(5):
        center = np.array([0.4, -0.2 + 0.1 * k, 0.5])
        term.move(0, center)
        if k == 2:
            term.set_obstacle(1, Box((0.3, 0.3, 0.3), (0.05, 0.05, 0.05)))
        if k == 3:
            term.set_obstacles([Sphere(center, 0.08), Capsule((0.2, 0, 0.2), (0.3, 0, 0.2), 0.03)])
        G = shaped.G(q)
        gam = shaped.christoffel(q)
        fresh = ShapedMetric(
            get_metric("panda"), [ObstacleTerm(term.obstacles, capacity=3, gain=2e-3, cutoff=0.3)]
        )
        np.testing.assert_allclose(G, fresh.G(q), atol=1e-12 * np.abs(G).max())
        if k == 4:
            np.testing.assert_allclose(gam, fresh.christoffel(q), atol=1e-9 * np.abs(gam).max())
    assert (shaped.build_count, term.build_count) == builds
    assert not np.array_equal(shaped.parameter_values(), params_before)
    # A parameter write, not a rebuild: cheap enough to be called per control tick (its
    # time is measured in benchmarks/shaping.py, not here).
    term.move(0, (0.4, 0.0, 0.5))
    assert (shaped.build_count, term.build_count) == builds
    fresh = ShapedMetric(
        get_metric("panda"), [ObstacleTerm(term.obstacles, capacity=3, gain=2e-3, cutoff=0.3)]
    )
    np.testing.assert_allclose(shaped.G(q), fresh.G(q), atol=1e-12 * np.abs(shaped.G(q)).max())


def test_capacity_and_obstacle_type_errors() -> None:
    with pytest.raises(CapacityExceeded, match="capacity is 2"):
        ObstacleTerm([Sphere((0, 0, 1), 0.1)] * 3, capacity=2)
    term = ObstacleTerm([Sphere((0, 0, 1), 0.1)] * 2, capacity=2)
    with pytest.raises(CapacityExceeded, match="capacity"):
        term.set_obstacle(2, Sphere((0, 0, 1), 0.1))
    with pytest.raises(CapacityExceeded, match="capacity"):
        term.set_obstacles([Sphere((0, 0, 1), 0.1)] * 3)
    with pytest.raises(InvalidGeometry, match=r"obstacles\[1\] is a dict.*Sphere, Box"):
        ObstacleTerm([Sphere((0, 0, 1), 0.1), {"center": (0, 0, 0)}])
    with pytest.raises(InvalidGeometry, match="Cylinder|tuple"):
        term.set_obstacle(0, ((0, 0, 0), 0.1))  # type: ignore[arg-type]
    with pytest.raises(InvalidTermArgument, match="index"):
        term.move(5, (0, 0, 0))
    with pytest.raises(InvalidTermArgument, match="profile 'quadratic'.*inverse_square"):
        ObstacleTerm([], profile="quadratic")
    with pytest.raises(InvalidTermArgument, match="gate"):
        ObstacleTerm([], gate="always")
    with pytest.raises(InvalidTermArgument, match="capacity"):
        ObstacleTerm([], capacity=0)
    with pytest.raises(InvalidTermArgument, match="gain"):
        ObstacleTerm([], gain=-1.0)


@pytest.mark.parametrize(
    ("make", "fragment"),
    [
        (lambda: Sphere((0, 0), 0.1), "Sphere.center"),
        (lambda: Sphere((0, 0, 0), -0.1), "Sphere.radius"),
        (lambda: Capsule((0, 0, 0), (1, 0, 0), 0.0), "Capsule.radius"),
        (lambda: Box((0, 0, 0), (0.1, -0.1, 0.1)), "half_extents"),
        (lambda: Box((0, 0, 0), (0.1, 0.1, 0.1), np.diag([1.0, 1.0, -1.0])), "rotation"),
        (lambda: HalfSpace((0, 0, 2.0), 0.0), "unit"),
        (lambda: HalfSpace((0, 0, 1.0), float("inf")), "offset"),
    ],
)
def test_bad_obstacles_raise(make, fragment: str) -> None:
    with pytest.raises(InvalidGeometry, match=fragment):
        make()


# -- geodesics under the shaped metric avoid the obstacle -----------------------------

AVOID_PAIRS = 20
AVOID_STEPS = 100  # RK4 steps of the logs; the check integrates 4x finer
AVOID_RADIUS = {"planar2": 0.10, "panda": 0.08}  # obstacle radius [m]


def _avoidance_case(robot, base, shaped, term, rng):
    """One well-posed start/goal pair and obstacle, or None to draw again.

    The obstacle sits beside the middle of the unshaped geodesic, next to the outermost
    (last) collision sphere and pushed radially outward, so that it overlaps that sphere's
    path by half its radius; start and goal keep >= 5 cm clearance, and the obstacle's
    centre is >= 2 cm from every sphere's path (it grows from a point beside the path).
    """
    from geosyn.metrics.geodesic import exp, log_solve

    radius = AVOID_RADIUS[robot.name]
    q0 = robot.random_q(rng, margin=0.3)
    q1 = robot.random_q(rng, margin=0.3)
    dq = q1 - q0
    dq *= rng.uniform(0.8, 1.6) / np.linalg.norm(dq)
    q1 = np.clip(q0 + dq, robot.q_min + 0.3, robot.q_max - 0.3)
    v_free = log_solve(base, q0, q1, steps=AVOID_STEPS).v0
    free = exp(base, q0, v_free, 1.0, AVOID_STEPS)
    mid = _sphere_kinematics(robot, free.q[AVOID_STEPS // 2])
    radial = [np.linalg.norm(x[:2]) for x, _, _ in mid]
    if int(np.argmax(radial)) != len(mid) - 1:
        return None
    x, _, r_s = mid[-1]
    out = np.array([x[0], x[1], 0.0]) / np.linalg.norm(x[:2])
    center = x + (radius + r_s - 0.5 * radius) * out
    term.set_obstacles([Sphere(center, 1e-3)])
    if min(term.min_clearance(q) for q in free.q) < 0.02:
        return None
    term.set_obstacles([Sphere(center, radius)])
    free_clearance = min(term.min_clearance(q) for q in free.q)
    if free_clearance > -0.2 * 0.5 * radius:
        return None
    if min(term.min_clearance(q0), term.min_clearance(q1)) < 0.05:
        return None
    return q0, q1, v_free, free, center, radius, free_clearance


@pytest.mark.slow
@pytest.mark.parametrize("name", ["planar2", "panda"])
def test_shaped_geodesics_keep_clear_of_a_sphere_obstacle(name: str) -> None:
    """20 seeded pairs whose unshaped geodesic passes through a sphere: log under the
    shaped metric keeps every collision sphere clear, checked on a 4x finer integration."""
    from geosyn.metrics.geodesic import exp, log_solve, path_energy

    robot = get_robot(name)
    base = get_metric(name)
    term = ObstacleTerm([], capacity=1, gain=1e-2, cutoff=0.4)
    shaped = ShapedMetric(base, [term])
    rng = np.random.default_rng(60)
    clearances, extra, free_clearances = [], [], []
    methods: dict[str, int] = {}
    builds = None
    while len(clearances) < AVOID_PAIRS:
        case = _avoidance_case(robot, base, shaped, term, rng)
        if case is None:
            continue
        q0, q1, v_free, free, center, radius, free_clearance = case
        # Plain log under the shaped metric, warm-started from the unshaped geodesic; where
        # Newton alone fails it follows the obstacles grown from points (parameter homotopy).
        res = log_solve(shaped, q0, q1, v_init=v_free, steps=AVOID_STEPS, max_iter=200)
        methods[res.method] = methods.get(res.method, 0) + 1
        fine = exp(shaped, q0, res.v0, 1.0, 4 * AVOID_STEPS)
        # The log's solution is a geodesic: a 4x finer integration lands on the goal.
        assert np.abs(fine.q[-1] - q1).max() < 1e-3
        clearances.append(min(term.min_clearance(q) for q in fine.q))
        free_clearances.append(free_clearance)
        e_free = path_energy(base, free.t, free.q)
        extra.append(path_energy(base, fine.t, fine.q) / e_free - 1.0)
        if builds is None:
            builds = shaped.build_count
    assert max(free_clearances) < 0.0  # every unshaped geodesic passes through the obstacle
    assert min(clearances) > 0.0, clearances
    assert shaped.build_count == builds  # moving/resizing the obstacle rebuilt nothing
    print(
        f"\n{name}: {AVOID_PAIRS} pairs, unshaped min clearance {min(free_clearances):.4f} m, "
        f"shaped min clearance {min(clearances):.4f} m (median {np.median(clearances):.4f}); "
        f"extra energy under the unshaped metric: median {np.median(extra):.3f}, "
        f"max {max(extra):.3f} (relative); log methods {methods}"
    )


def test_parameter_homotopy_shrinks_obstacles_about_their_centres() -> None:
    """s = 0: every obstacle a 1 mm ball at its centre; s = 1: the obstacles themselves."""
    from geosyn.metrics.geodesic.continuation import parameter_homotopy

    term = ObstacleTerm(
        [Sphere((1.0, 0.5, 0.2), 0.1), Box((0.3, -0.2, 0.4), (0.1, 0.2, 0.05))], capacity=3
    )
    shaped = ShapedMetric(get_metric("panda"), [term])
    now = shaped.parameter_values().copy()
    np.testing.assert_array_equal(parameter_homotopy(shaped, 1.0), now)
    n_slots = 3 * PARAMS_PER_OBSTACLE  # then the profile's gain and cutoff, kept
    at0 = parameter_homotopy(shaped, 0.0)[:n_slots].reshape(3, PARAMS_PER_OBSTACLE)
    slots = now[:n_slots].reshape(3, PARAMS_PER_OBSTACLE)
    np.testing.assert_array_equal(parameter_homotopy(shaped, 0.0)[n_slots:], [1e-3, 0.2])
    np.testing.assert_array_equal(at0[:, :12], slots[:, :12])  # centres and rotations kept
    np.testing.assert_array_equal(at0[:, 12:15], 0.0)
    np.testing.assert_allclose(at0[:, 15], HOMOTOPY_RADIUS, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(at0[:, 16], slots[:, 16])  # active flags kept
    half = parameter_homotopy(shaped, 0.5)[:n_slots].reshape(3, PARAMS_PER_OBSTACLE)
    np.testing.assert_allclose(half[0, 15], 0.5 * 0.1 + 0.5 * HOMOTOPY_RADIUS, rtol=1e-15)
    np.testing.assert_array_equal(shaped.parameter_values(), now)  # the metric is unchanged
    assert parameter_homotopy(get_metric("panda"), 0.0) is None  # unshaped: no homotopy


def test_exp_sees_moved_obstacle_without_rebuild() -> None:
    """exp reads the obstacle parameters at call time: after `move`, it equals exp under a
    freshly built metric with the obstacle at the new place."""
    from geosyn.metrics.geodesic import exp

    base = get_metric("planar2")
    q0, v0 = np.array([0.3, 0.4]), np.array([0.8, -0.5])
    term = ObstacleTerm([Sphere((1.0, 1.6, 0.0), 0.1)], capacity=2, gain=1e-2, cutoff=0.5)
    shaped = ShapedMetric(base, [term])
    first = exp(shaped, q0, v0, 1.0, 100)
    builds = shaped.build_count
    term.move(0, (1.3, 1.3, 0.0))
    moved = exp(shaped, q0, v0, 1.0, 100)
    fresh_term = ObstacleTerm([Sphere((1.3, 1.3, 0.0), 0.1)], capacity=2, gain=1e-2, cutoff=0.5)
    fresh = exp(ShapedMetric(base, [fresh_term]), q0, v0, 1.0, 100)
    assert np.abs(moved.q - first.q).max() > 1e-3  # the obstacle matters
    np.testing.assert_allclose(moved.q, fresh.q, atol=1e-12)
    assert shaped.build_count == builds


def test_smooth_distance_option_is_conservative_within_its_bound() -> None:
    from geosyn.world.smooth import error_bound

    robot = get_robot("panda")
    obstacles = _scene()
    exact = ObstacleTerm(obstacles, capacity=5).bind(robot)
    smooth = ObstacleTerm(obstacles, capacity=5, distance="smooth").bind(robot)
    rng = np.random.default_rng(21)
    for _ in range(10):
        q = robot.random_q(rng)
        diff = smooth.clearances(q) - exact.clearances(q)
        assert diff.max() <= 1e-12 and diff.min() >= -error_bound()
    with pytest.raises(InvalidTermArgument, match="distance 'fuzzy' is unknown"):
        ObstacleTerm(obstacles, distance="fuzzy")


def test_symbolic_clearances_rows_and_softmin() -> None:
    import casadi as ca

    robot = get_robot("panda")
    obstacles = _scene()
    term = ObstacleTerm(obstacles, capacity=5).bind(robot)
    q = ca.SX.sym("q", robot.nv)
    p = term.symbolic_parameters()
    rows = ca.Function("rows", [q, p], [term.symbolic_clearances(q)])
    soft = ca.Function("soft", [q, p], [term.symbolic_clearances(q, softmin=500.0)])
    qv = robot.random_q(np.random.default_rng(22))
    c = term.clearances(qv)  # (spheres, 4 active obstacles)
    all_rows = np.asarray(rows(qv, term.parameter_values())).reshape(len(term.spheres), 5)
    np.testing.assert_allclose(all_rows[:, :4], c, atol=1e-12)
    np.testing.assert_array_equal(all_rows[:, 4], 10.0)  # the empty slot
    s = np.asarray(soft(qv, term.parameter_values())).ravel()
    assert np.all(s[:4] <= c.min(axis=0) + 1e-12)
    assert np.all(s[:4] >= c.min(axis=0) - np.log(len(term.spheres)) / 500.0)
