"""World payloads: the one description of a held object (mass, com, inertia, frame)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from geosyn.world import InvalidGeometry, Payload

INERTIA = np.array([[0.021, 0.0015, -0.0007], [0.0015, 0.030, 0.0022], [-0.0007, 0.0022, 0.026]])


def test_default_is_a_solid_ball() -> None:
    p = Payload("hand", 2.0, (0.0, 0.0, 0.05), radius=0.04)
    np.testing.assert_array_equal(p.rotational_inertia(), np.eye(3) * 0.4 * 2.0 * 0.04**2)
    np.testing.assert_array_equal(p.rotational_inertia(0.5), np.eye(3) * 0.4 * 0.5 * 0.04**2)
    moments, axes = p.principal_inertia(0.5)
    np.testing.assert_array_equal(moments, np.full(3, 0.4 * 0.5 * 0.04**2))
    np.testing.assert_array_equal(axes, np.eye(3))
    point = Payload("hand", 2.0, radius=0.0)
    np.testing.assert_array_equal(point.rotational_inertia(), np.zeros((3, 3)))


def test_given_inertia_scales_with_mass_and_diagonalises() -> None:
    p = Payload("hand", 2.0, inertia=INERTIA)
    np.testing.assert_array_equal(p.rotational_inertia(), INERTIA)
    np.testing.assert_allclose(p.rotational_inertia(3.0), 1.5 * INERTIA, rtol=1e-15)
    for mass in (None, 3.0):
        moments, axes = p.principal_inertia(mass)
        assert np.linalg.det(axes) == pytest.approx(1.0, abs=1e-14)
        np.testing.assert_allclose(
            axes @ np.diag(moments) @ axes.T, p.rotational_inertia(mass), atol=1e-16
        )
    # the spatial inertia Pinocchio builds from it is the same rigid body
    body = pin.Inertia(p.mass, np.array(p.com), p.rotational_inertia())
    np.testing.assert_allclose(body.inertia, INERTIA, atol=1e-16)


def test_payloads_are_frozen_values() -> None:
    a = Payload("hand", 1.0, np.array([0.0, 0.0, 0.1]), INERTIA, name="box")
    b = Payload("hand", 1.0, (0.0, 0.0, 0.1), tuple(map(tuple, INERTIA)), name="box")
    assert a == b and hash(a) == hash(b)
    assert a != Payload("hand", 1.0, (0.0, 0.0, 0.1), name="box")


@pytest.mark.parametrize(
    ("kwargs", "name", "fragment"),
    [
        ({"frame": 3}, "Payload.frame", "frame name"),
        ({"mass": -1.0}, "Payload.mass", "kg"),
        ({"mass": float("nan")}, "Payload.mass", "finite"),
        ({"com": (0.0, 0.0)}, "Payload.com", r"shape \(3,\)"),
        ({"radius": -0.1}, "Payload.radius", "m"),
        ({"inertia": -np.eye(3) * 0.01}, "Payload.inertia", "positive definite"),
        ({"inertia": np.diag([0.01, 0.0, 0.01])}, "Payload.inertia", "positive definite"),
        ({"inertia": [[0.01, 0.002, 0], [0.0, 0.01, 0], [0, 0, 0.01]]}, "Payload.inertia", "symm"),
        ({"inertia": np.diag([0.01, 0.01, 0.05])}, "Payload.inertia", "triangle"),
        ({"inertia": np.eye(2)}, "Payload.inertia", r"\(3, 3\)"),
        ({"mass": 0.0, "inertia": INERTIA}, "Payload.inertia", "mass 0"),
        ({"name": 5}, "Payload.name", "str"),
    ],
)
def test_bad_fields_name_the_field(kwargs: dict, name: str, fragment: str) -> None:
    args = {"frame": "hand", "mass": 1.0} | kwargs
    with pytest.raises(InvalidGeometry, match=fragment) as info:
        Payload(**args)
    assert info.value.name == name
    assert name in str(info.value)
