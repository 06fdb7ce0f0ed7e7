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


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The slow-marked tests first (otherwise in collection order): the 2 workers of
    `make test` then end on short tests instead of one of them on a long one collected
    late. Whole suite, 2 workers, empty geosyn cache, alternating: 489 / 476 s against
    538 / 512 s in collection order (`benchmarks/RESULTS.md`, issue 22)."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)
