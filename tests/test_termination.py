"""SIGTERM ends a run or sweep even when Python swallows the handler's exception
(experiments/run/termination.py)."""

from __future__ import annotations

import signal
import weakref

import pytest

from geosyn.experiments.config.loader import load_config
from geosyn.experiments.run import termination
from geosyn.experiments.run.runner import run_experiment


@pytest.fixture(autouse=True)
def _clean_state():
    termination._received = None
    yield
    termination._received = None


def _swallowed_sigterm() -> None:
    """Deliver the handler inside a finaliser, where Python discards its SystemExit."""

    class Thing:
        pass

    thing = Thing()
    weakref.finalize(thing, termination._handler, signal.SIGTERM, None)
    del thing  # prints "Exception ignored ... SystemExit: 143" and carries on


# The swallowed SystemExit is reported by Python as an unraisable exception: expected here.
swallowed = pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")


@swallowed
def test_swallowed_sigterm_is_remembered() -> None:
    _swallowed_sigterm()
    with pytest.raises(SystemExit) as info:
        termination.raise_if_terminated()
    assert info.value.code == 128 + signal.SIGTERM


@swallowed
def test_run_after_a_swallowed_sigterm_commits_nothing(tmp_path) -> None:
    cfg, _ = load_config(
        "planar2_geodesic_vs_euclidean", ["simulation.duration=0.2", "outputs.plots=false"]
    )
    _swallowed_sigterm()
    with pytest.raises(SystemExit):
        run_experiment(cfg, tmp_path / "run", progress=False, quiet=True)
    assert list(tmp_path.iterdir()) == [], "no run directory and no temporary left behind"


def test_install_resets_the_state() -> None:
    termination._received = signal.SIGTERM
    previous = termination.install()
    try:
        termination.raise_if_terminated()  # nothing pending after a fresh install
    finally:
        termination.restore(previous)


def test_sigterm_exits_restores_the_previous_handler() -> None:
    before = signal.getsignal(signal.SIGTERM)
    with termination.sigterm_exits():
        assert signal.getsignal(signal.SIGTERM) is termination._handler
    assert signal.getsignal(signal.SIGTERM) == before
