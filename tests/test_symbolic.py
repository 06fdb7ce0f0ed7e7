"""Tests of geosyn.robots.symbolic: the SX rigid-body algorithms against Pinocchio."""

from __future__ import annotations

import sys
from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from geosyn.core import GeosynError, InvalidArgument
from geosyn.robots import symbolic

N_SAMPLES = 200
TOL = 1e-12
GRAVITY = np.array([0.3, -0.2, -9.81])  # [m/s^2], tilted so every axis is exercised


def _robots_dir() -> Path:
    """example-robot-data's robots folder, found next to the pinocchio the tests import."""
    candidates = [p for p in Path(pin.__file__).resolve().parents if p.name == "cmeel.prefix"]
    ver = f"python{sys.version_info.major}.{sys.version_info.minor}"
    candidates.append(Path(sys.prefix) / "lib" / ver / "site-packages" / "cmeel.prefix")
    for prefix in candidates:
        robots = prefix / "share" / "example-robot-data" / "robots"
        if robots.is_dir():
            return robots
    raise FileNotFoundError(f"example-robot-data robots not found under {candidates}")


def _panda() -> pin.Model:
    return pin.buildModelFromUrdf(str(_robots_dir() / "panda_description" / "urdf" / "panda.urdf"))


def _random_se3(rng: np.random.Generator) -> pin.SE3:
    return pin.SE3(pin.rpy.rpyToMatrix(*rng.uniform(-np.pi, np.pi, 3)), rng.normal(0, 0.3, 3))


def _random_inertia(rng: np.random.Generator) -> pin.Inertia:
    a = rng.normal(size=(3, 3))
    return pin.Inertia(rng.uniform(0.5, 3.0), rng.normal(0, 0.1, 3), a @ a.T + 0.1 * np.eye(3))


def _zoo() -> pin.Model:
    """A branching tree with every supported joint type, random placements and inertias.

    Joints are added depth first, as Pinocchio requires (its crba assumes every subtree
    occupies consecutive velocity indices).
    """
    rng = np.random.default_rng(7)

    def unit(x: np.ndarray) -> np.ndarray:
        return x / np.linalg.norm(x)

    joints = [
        (0, pin.JointModelRX()),
        (1, pin.JointModelRY()),
        (2, pin.JointModelRZ()),
        (2, pin.JointModelRevoluteUnaligned(unit(rng.normal(size=3)))),
        (4, pin.JointModelPX()),
        (1, pin.JointModelPY()),
        (6, pin.JointModelPZ()),
        (7, pin.JointModelPrismaticUnaligned(unit(rng.normal(size=3)))),
        (6, pin.JointModelRevoluteUnaligned(unit(rng.normal(size=3)))),
    ]
    model = pin.Model()
    for k, (parent, joint) in enumerate(joints, start=1):
        jid = model.addJoint(parent, joint, _random_se3(rng), f"j{k}")
        model.appendBodyToJoint(jid, _random_inertia(rng), pin.SE3.Identity())
        model.addJointFrame(jid)
        model.addBodyFrame(f"b{k}", jid, _random_se3(rng), -1)
    return model


def _with_armature(model: pin.Model) -> pin.Model:
    model = model.copy()
    model.armature = np.linspace(0.05, 0.4, model.nv)
    return model


# Zero armature is covered by the sample manipulator, the real robot by the panda.
MODELS = {
    "sample": pin.buildSampleModelManipulator,
    "panda_armature": lambda: _with_armature(_panda()),
    "zoo_armature": lambda: _with_armature(_zoo()),
}


def _symmetric(upper: np.ndarray) -> np.ndarray:
    # pin.crba fills only the upper triangle.
    return np.triu(upper) + np.triu(upper, 1).T


def _assert_close(actual: np.ndarray, expected: np.ndarray, what: str) -> None:
    actual = np.asarray(actual, dtype=float).reshape(np.shape(expected))
    scale = max(float(np.max(np.abs(expected))), 1e-300)
    err = float(np.max(np.abs(actual - expected)))
    assert err <= TOL * scale, f"{what}: max error {err:.3e} > {TOL:g} * {scale:.3e}"


class Case:
    """One model, its compiled-once CasADi functions and seeded random samples."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.model = MODELS[name]()
        self.model.gravity.linear = GRAVITY
        self.data = self.model.createData()
        nq, nv = self.model.nq, self.model.nv
        q = ca.SX.sym("q", nq)
        v = ca.SX.sym("v", nv)
        a = ca.SX.sym("a", nv)
        self.fns = symbolic.dynamics_functions(self.model, GRAVITY)
        self.placements = ca.Function(
            "placements",
            [q],
            [
                e
                for frame in range(self.model.nframes)
                for e in symbolic.frame_placement(self.model, q, frame)
            ],
        )
        self.joints = ca.Function(
            "joints", [q], [e for pair in symbolic.joint_placements(self.model, q) for e in pair]
        )
        # One frame per joint, the last one attached to it (a body frame, usually offset
        # from the joint): the Jacobian of every other frame differs only in that offset.
        self.jacobian_frames = sorted(
            {
                max(
                    f
                    for f in range(self.model.nframes)
                    if self.model.frames[f].parentJoint == joint
                )
                for joint in range(1, self.model.njoints)
            }
        )
        self.jacobians = {
            ref: ca.Function(
                f"jacobians_{ref}",
                [q],
                [symbolic.frame_jacobian(self.model, q, f, ref) for f in self.jacobian_frames],
            )
            for ref in ("world_aligned", "local")
        }
        self.rnea_sx = ca.Function(
            "rnea_sx", [q, v, a], [symbolic.rnea(self.model, q, v, a, ca.SX(GRAVITY))]
        )
        rng = np.random.default_rng(12345)
        self.samples = [
            (
                rng.uniform(-np.pi, np.pi, nq),
                rng.normal(0.0, 2.0, nv),
                rng.normal(0.0, 5.0, nv),
                rng.normal(0.0, 20.0, nv),
            )
            for _ in range(N_SAMPLES)
        ]


@pytest.fixture(scope="module", params=list(MODELS))
def case(request: pytest.FixtureRequest) -> Case:
    return Case(request.param)


def test_rnea_matches_pinocchio(case: Case) -> None:
    for q, v, a, _ in case.samples:
        expected = pin.rnea(case.model, case.data, q, v, a).copy()
        _assert_close(case.fns.rnea(q, v, a).full(), expected, "rnea")
        # Gravity as an SX argument instead of a folded constant gives the same result.
        _assert_close(case.rnea_sx(q, v, a).full(), expected, "rnea (SX gravity)")


def test_bias_matches_nonlinear_effects(case: Case) -> None:
    for q, v, _, _ in case.samples:
        expected = pin.nonLinearEffects(case.model, case.data, q, v).copy()
        _assert_close(case.fns.bias(q, v).full(), expected, "bias")


def test_crba_matches_pinocchio(case: Case) -> None:
    for q, _, _, _ in case.samples:
        expected = _symmetric(pin.crba(case.model, case.data, q).copy())
        actual = case.fns.M(q).full()
        _assert_close(actual, expected, "crba")
        np.testing.assert_array_equal(actual, actual.T)


def test_aba_matches_pinocchio(case: Case) -> None:
    for q, v, _, tau in case.samples:
        expected = pin.aba(case.model, case.data, q, v, tau).copy()
        _assert_close(case.fns.aba(q, v, tau).full(), expected, "aba")


def test_geodesic_acceleration_is_aba_without_gravity_and_torque(case: Case) -> None:
    model = case.model.copy()
    model.gravity.linear = np.zeros(3)
    data = model.createData()
    for q, v, _, _ in case.samples:
        expected = pin.aba(model, data, q, v, np.zeros(model.nv)).copy()
        _assert_close(case.fns.geodesic_acceleration(q, v).full(), expected, "geodesic acc.")


def test_aba_inverts_rnea(case: Case) -> None:
    for q, v, a, _ in case.samples[:50]:
        tau = case.fns.rnea(q, v, a)
        np.testing.assert_allclose(case.fns.aba(q, v, tau).full().ravel(), a, atol=1e-9)


def test_mass_matrix_is_spd_and_rnea_splits(case: Case) -> None:
    zero = np.zeros(case.model.nv)
    for q, v, a, _ in case.samples[:50]:
        mass = case.fns.M(q).full()
        assert np.linalg.eigvalsh(mass).min() > 0.0
        h = case.fns.bias(q, v).full().ravel()
        np.testing.assert_allclose(
            case.fns.rnea(q, v, a).full().ravel(), mass @ a + h, rtol=1e-11, atol=1e-9
        )
        # C(q, v) v is quadratic in v: h(q, 2v) - g(q) == 4 (h(q, v) - g(q)).
        g = case.fns.bias(q, zero).full().ravel()
        np.testing.assert_allclose(
            case.fns.bias(q, 2.0 * v).full().ravel() - g, 4.0 * (h - g), rtol=1e-10, atol=1e-9
        )


def test_frame_placements_match_pinocchio(case: Case) -> None:
    for q, _, _, _ in case.samples:
        pin.framesForwardKinematics(case.model, case.data, q)
        out = case.placements(q)
        for frame in range(case.model.nframes):
            expected = case.data.oMf[frame]
            _assert_close(out[2 * frame].full(), expected.rotation, f"R of frame {frame}")
            _assert_close(out[2 * frame + 1].full(), expected.translation, f"p of frame {frame}")


def test_joint_placements_match_pinocchio(case: Case) -> None:
    for q, _, _, _ in case.samples:
        pin.forwardKinematics(case.model, case.data, q)
        out = case.joints(q)
        assert len(out) == 2 * case.model.njoints
        for joint in range(case.model.njoints):
            expected = case.data.oMi[joint]
            _assert_close(out[2 * joint].full(), expected.rotation, f"R of joint {joint}")
            _assert_close(out[2 * joint + 1].full(), expected.translation, f"p of joint {joint}")


@pytest.mark.parametrize(
    ("reference", "pin_reference"),
    [("world_aligned", pin.LOCAL_WORLD_ALIGNED), ("local", pin.LOCAL)],
)
def test_frame_jacobians_match_pinocchio(case: Case, reference: str, pin_reference) -> None:
    fun = case.jacobians[reference]
    for q, _, _, _ in case.samples:
        out = fun(q)
        for k, frame in enumerate(case.jacobian_frames):
            expected = pin.computeFrameJacobian(case.model, case.data, q, frame, pin_reference)
            _assert_close(out[k].full(), expected, f"{reference} Jacobian of frame {frame}")


def test_numeric_inputs_fold_to_constants() -> None:
    model = _with_armature(_panda())
    model.gravity.linear = GRAVITY
    rng = np.random.default_rng(3)
    q, v, a = rng.normal(size=(3, model.nv))
    tau = symbolic.rnea(model, q, v, a, GRAVITY)
    assert tau.is_constant()
    _assert_close(np.array(ca.DM(tau)), pin.rnea(model, model.createData(), q, v, a), "rnea")


def test_graph_sizes_stay_small() -> None:
    model = _panda()
    fns = symbolic.dynamics_functions(model, np.array([0.0, 0.0, -9.81]))
    q = ca.SX.sym("q", model.nq)
    v = ca.SX.sym("v", model.nv)
    a = ca.SX.sym("a", model.nv)
    sizes = {f.name(): f.n_nodes() for f in fns}
    sizes["rnea (no cse)"] = symbolic.count_nodes(symbolic.rnea(model, q, v, a, np.zeros(3)))
    print("panda SX node counts:", sizes)
    # Guards against graph blow-ups (measured: M 774, rnea 1332, aba 2294, geodesic 2200).
    assert sizes["M"] < 1000
    assert sizes["rnea"] < 1600
    assert sizes["aba"] < 2800
    assert sizes["geodesic_acceleration"] < 2700


def test_dynamics_functions_names() -> None:
    fns = symbolic.dynamics_functions(pin.buildSampleModelManipulator(), np.zeros(3))
    assert fns._fields == ("M", "rnea", "bias", "aba", "geodesic_acceleration")
    assert [f.name() for f in fns] == list(fns._fields)
    assert fns.rnea.name_in() == ["q", "v", "a"]
    assert fns.aba.name_in() == ["q", "v", "tau"]
    assert fns.geodesic_acceleration.name_in() == ["q", "v"]


def test_unsupported_joint_is_named() -> None:
    model = pin.buildSampleModelManipulator()
    model.addJoint(3, pin.JointModelTranslation(), pin.SE3.Identity(), "slider_xyz")
    with pytest.raises(InvalidArgument, match="slider_xyz.*JointModelTranslation"):
        symbolic.crba(model, ca.SX.sym("q", model.nq))
    assert issubclass(InvalidArgument, GeosynError)


def test_floating_base_is_rejected() -> None:
    model = pin.buildModelFromUrdf(
        str(_robots_dir() / "panda_description" / "urdf" / "panda.urdf"),
        pin.JointModelFreeFlyer(),
    )
    with pytest.raises(InvalidArgument, match="nq"):
        symbolic.rnea(
            model, np.zeros(model.nq), np.zeros(model.nv), np.zeros(model.nv), np.zeros(3)
        )


def test_bad_arguments_raise() -> None:
    model = pin.buildSampleModelManipulator()
    q = ca.SX.sym("q", model.nq)
    with pytest.raises(InvalidArgument, match="q: expected"):
        symbolic.crba(model, ca.SX.sym("q", model.nq + 1))
    with pytest.raises(InvalidArgument, match="MX"):
        symbolic.crba(model, ca.MX.sym("q", model.nq))
    with pytest.raises(InvalidArgument, match="gravity"):
        symbolic.bias(model, q, q, np.zeros(2))
    with pytest.raises(InvalidArgument, match="finite"):
        symbolic.bias(model, q, q, np.array([0.0, np.nan, 0.0]))
    with pytest.raises(InvalidArgument, match="frame_id"):
        symbolic.frame_placement(model, q, model.nframes)
    with pytest.raises(InvalidArgument, match="reference"):
        symbolic.frame_jacobian(model, q, 1, reference="world")
    with pytest.raises(InvalidArgument, match="symbolic"):
        symbolic.dynamics_functions(model, ca.SX.sym("g", 3))
    with pytest.raises(InvalidArgument, match="pinocchio.Model"):
        symbolic.crba("panda", q)


def test_all_names_resolve() -> None:
    for name in symbolic.__all__:
        assert hasattr(symbolic, name), name
