"""Collocation of the geodesic energy (`geosyn.metrics.geodesic.collocation`).

References: the shooting log map (`log_solve`, an independent method) and the exact
sphere-obstacle clearances of `ObstacleTerm.clearances`.
"""

from __future__ import annotations

import numpy as np
import pytest

from geosyn.core.errors import InvalidArgument
from geosyn.metrics import Collocation, KineticEnergyMetric, exp, log_solve
from geosyn.metrics.shaping import ObstacleTerm, ShapedMetric
from geosyn.robots import load_robot
from geosyn.world import Sphere

Q0, Q1 = np.array([0.2, 0.3]), np.array([1.5, 1.8])
STEPS = 200


def _metrics() -> dict[str, object]:
    base = KineticEnergyMetric(load_robot("planar2"))
    # A sphere 4 cm from the unshaped geodesic, inside the cutoff: the shaped one bends.
    term = ObstacleTerm([Sphere((-0.3, 1.2, 0.0), 0.1)], capacity=1, gain=1e-3)
    return {"unshaped": base, "sphere-shaped": ShapedMetric(base, [term])}


@pytest.mark.parametrize("name", ["unshaped", "sphere-shaped"])
def test_collocation_agrees_with_shooting(name: str) -> None:
    """Collocation (refined by shooting from its own v0) = shooting from the straight line."""
    metric = _metrics()[name]
    col = Collocation(metric, nodes=24, joint_limits=False)  # type: ignore[arg-type]
    res = col.solve(Q0, Q1, steps=STEPS)
    assert res.kind == "geodesic", res.message
    ref = log_solve(metric, Q0, Q1, steps=STEPS)  # type: ignore[arg-type]
    assert np.abs(res.v0 - ref.v0).max() < 1e-6
    path = exp(metric, Q0, ref.v0, 1.0, STEPS).q  # type: ignore[arg-type]
    assert np.abs(res.q - path).max() < 1e-6
    assert res.geodesic_residual < 1e-8


def test_discrete_geodesic_converges_at_second_order() -> None:
    """Unrefined nodes approach the geodesic as 1/N^2: doubling N cuts the error ~4x."""
    metric = _metrics()["unshaped"]
    v0 = log_solve(metric, Q0, Q1, steps=STEPS).v0  # type: ignore[arg-type]
    geo = exp(metric, Q0, v0, 1.0, 960)  # type: ignore[arg-type]
    errors = []
    for N in (12, 24, 48):
        res = Collocation(metric, nodes=N, joint_limits=False).solve(Q0, Q1, refine=False)  # type: ignore[arg-type]
        assert res.kind == "discrete geodesic", res.message
        errors.append(np.abs(res.nodes - geo.q[:: 960 // N]).max())
    assert errors[0] < 0.05
    assert 3.0 < errors[0] / errors[1] < 5.0 and 3.0 < errors[1] / errors[2] < 5.0


def _sphere_on_the_line() -> tuple[KineticEnergyMetric, ObstacleTerm, np.ndarray, np.ndarray]:
    """planar2 from q0 to q1 and a 0.15 m sphere where the straight line's tip passes at
    mid-path: (metric, obstacle term with 2 slots, q0, q1)."""
    robot = load_robot("planar2")
    q0, q1 = np.array([-0.6, 0.4]), np.array([0.6, 0.4])
    mid = 0.5 * (q0 + q1)
    tip = np.array([np.cos(mid[0]) + np.cos(mid.sum()), np.sin(mid[0]) + np.sin(mid.sum())])
    term = ObstacleTerm([Sphere((tip[0], tip[1], 0.0), 0.15)], capacity=2).bind(robot)
    return KineticEnergyMetric(robot), term, q0, q1


@pytest.mark.parametrize("softmin", [None, 1000.0])
def test_blocked_line_gives_constrained_path_with_margin(softmin: float | None) -> None:
    """A sphere on the straight line: the path keeps the margin and says it is constrained
    (per-sphere constraints, or their conservative smooth minimum per obstacle)."""
    metric, term, q0, q1 = _sphere_on_the_line()
    col = Collocation(
        metric, nodes=24, clearance=term, margin=0.01, joint_limits=False, softmin=softmin
    )
    res = col.solve(q0, q1)
    assert res.kind == "constrained" and res.active > 0, res.message
    mids = 0.5 * (res.nodes[1:] + res.nodes[:-1])  # also constrained (subdivisions=1)
    exact = np.array([term.clearances(q).min() for q in [*res.nodes[1:-1], *mids]])
    assert exact.min() > 0.01 - 1e-6
    if softmin is None:
        assert abs(res.min_clearance - exact.min()) < 1e-9
    else:  # conservative, within log(spheres) / softmin
        assert exact.min() - np.log(6) / softmin <= res.min_clearance <= exact.min() + 1e-12
    # the energy is above the unconstrained geodesic's and the path goes round the sphere
    free = Collocation(metric, nodes=24, joint_limits=False).solve(q0, q1, refine=False)
    assert res.energy > free.energy
    assert np.isnan(res.geodesic_residual)


def _blocked_planar2() -> tuple[Collocation, Collocation, ObstacleTerm, np.ndarray, np.ndarray]:
    """planar2, a sphere on the straight line's tip path; NLPs with 1 and 3 subdivisions."""
    metric, term, q0, q1 = _sphere_on_the_line()
    kw = dict(nodes=12, clearance=term, margin=0.01, joint_limits=False)
    return (Collocation(metric, **kw), Collocation(metric, subdivisions=3, **kw),  # type: ignore[arg-type]
            term, q0, q1)  # fmt: skip


def test_subdivisions_keep_the_margin_at_every_quarter_point() -> None:
    """With 3 subdivisions, the path checked 4x finer than its nodes keeps the margin
    (exact clearance, reference `ObstacleTerm.clearances`) at every checked point."""
    from geosyn.metrics.planning.planner import densify

    _, fine, term, q0, q1 = _blocked_planar2()
    res = fine.solve(q0, q1)
    assert res.kind == "constrained", res.message
    exact = np.array([term.clearances(q).min() for q in densify(res.nodes, 4)])
    assert exact.min() > 0.01 - 1e-6
    assert res.multipliers is not None and res.multipliers[1].size == 2 * (11 + 3 * 12)


def test_warm_start_from_own_solution_and_from_fewer_subdivisions() -> None:
    """A warm start from a converged result of the same NLP takes fewer iterations than the
    cold solve and stops at the same nodes; one from the NLP with midpoints only reaches
    the cold solution of the NLP with quarter points."""
    coarse, fine, _, q0, q1 = _blocked_planar2()
    first = coarse.solve(q0, q1, refine=False)
    assert first.kind == "constrained", first.message
    again = coarse.solve(q0, q1, warm=first, refine=False)
    assert again.success and again.iterations < first.iterations, again.message
    np.testing.assert_allclose(again.nodes, first.nodes, atol=1e-6)
    cold = fine.solve(q0, q1, init=first.nodes, refine=False)
    warm = fine.solve(q0, q1, warm=first, refine=False)
    assert warm.kind == cold.kind == "constrained"
    np.testing.assert_allclose(warm.nodes, cold.nodes, atol=1e-5)
    with pytest.raises(InvalidArgument, match="warm"):
        Collocation(KineticEnergyMetric(load_robot("planar2")), nodes=6,
                    joint_limits=False).solve(q0, q1, warm=first)  # fmt: skip


def test_point_times_order_the_lower_bounds_of_the_constraints() -> None:
    """`point_times` lists the constrained points in the order of `lower`'s rows: raising
    the bound of one point raises the exact clearance (reference `ObstacleTerm.clearances`)
    of the configuration at that time, linear between the nodes, to it."""
    from geosyn.metrics.geodesic.collocation_parts import interpolate_path

    _, fine, term, q0, q1 = _blocked_planar2()
    times = fine.point_times
    expected = [
        *(np.arange(1, 12) / 12),
        *((np.arange(12)[:, None] + [0.25, 0.5, 0.75]) / 12).T.ravel(),
    ]
    np.testing.assert_allclose(times, expected, atol=1e-15)
    base = fine.solve(q0, q1, refine=False)
    lower = np.full((len(times), fine.constraints_per_node), 0.01)
    i = int(np.argmin(np.abs(times - 13 / 24)))  # a midpoint near the sphere
    lower[i] = 0.06
    raised = fine.solve(q0, q1, refine=False, lower=lower)
    assert raised.kind == "constrained", raised.message
    at = interpolate_path(raised.nodes, np.linspace(0, 1, 13), 48, 2)[26]  # t = 13 / 24
    assert abs(times[i] - 13 / 24) < 1e-15
    assert term.clearances(at).min() > 0.06 - 1e-6 > term.clearances(
        interpolate_path(base.nodes, np.linspace(0, 1, 13), 48, 2)[26]).min()  # fmt: skip
    with pytest.raises(InvalidArgument, match="lower must have shape"):
        fine.solve(q0, q1, lower=lower[1:])


def test_initial_path_at_times_and_small_barrier() -> None:
    """A 6-node solution as the initial path of the 12-node NLP (`init_t`: interpolated in
    time, so every other node starts exactly on it) solved with a small initial barrier
    parameter: the same solution as IPOPT's default barrier from that path, in fewer
    iterations."""
    from geosyn.metrics.geodesic.collocation_parts import interpolate_path

    _, fine, _, q0, q1 = _blocked_planar2()
    metric, term = fine.metric, fine.clearance
    six = Collocation(metric, nodes=6, clearance=term, margin=0.01, joint_limits=False,
                      subdivisions=3).solve(q0, q1, refine=False)  # fmt: skip
    t6 = np.linspace(0, 1, 7)
    np.testing.assert_array_equal(interpolate_path(six.nodes, t6, 12, 2)[::2], six.nodes)
    cold = fine.solve(q0, q1, init=six.nodes, init_t=t6, refine=False)
    seeded = fine.solve(q0, q1, init=six.nodes, init_t=t6, mu_init=1e-4, refine=False)
    assert seeded.kind == cold.kind == "constrained", seeded.message
    np.testing.assert_allclose(seeded.nodes, cold.nodes, atol=3e-5)  # measured 6e-6
    assert seeded.iterations < cold.iterations
    with pytest.raises(InvalidArgument, match="init_t must be increasing"):
        fine.solve(q0, q1, init=six.nodes, init_t=np.linspace(1, 0, 7))
