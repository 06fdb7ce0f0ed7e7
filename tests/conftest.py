"""Shared fixtures: robots and metrics are built once per session (loading is not free)."""

from __future__ import annotations

import functools

import pytest

from geosyn.metrics import KineticEnergyMetric
from geosyn.robots import Robot, load_robot

BUILTIN_NAMES = ("planar2", "planar3", "panda", "talos_arm", "ur5")


@functools.cache
def get_robot(name: str) -> Robot:
    """A built-in robot, loaded once per test session."""
    return load_robot(name)


@functools.cache
def get_metric(name: str, compile: bool = False) -> KineticEnergyMetric:
    """The kinetic-energy metric of a built-in robot, built once per test session."""
    return KineticEnergyMetric(get_robot(name), compile=compile)


@pytest.fixture(scope="session")
def planar2() -> Robot:
    return get_robot("planar2")


@pytest.fixture(scope="session")
def panda() -> Robot:
    return get_robot("panda")


@pytest.fixture(scope="session")
def talos_arm() -> Robot:
    return get_robot("talos_arm")
