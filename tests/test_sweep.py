"""Sweeps: grid x seeds, resume after an interruption, aggregate, process pool, Ray."""

from __future__ import annotations

import contextlib
import json
import os
import re
import sys
from pathlib import Path

import numpy as np
import pytest

import geosyn.experiments.sweep.run_sweep as sweep_mod
from geosyn.core.errors import InvalidArgument
from geosyn.experiments.errors import ConfigError, RunDirectoryExists
from geosyn.experiments.sweep import parse_grid, point_name, sweep

# Ray clusters on one machine find each other (/tmp/ray): with `pytest -n`, one worker
# runs every test that starts one.
pytestmark = pytest.mark.xdist_group("ray")

SRC = "planar2_geodesic_vs_euclidean"
BASE = [
    "outputs.plots=false",
    "params.steps=60",
    "params.duration=0.3",
    "simulation.duration=0.3",
    "disturbances=[{type: torque_noise, std: 0.05}]",
]


def test_parse_grid():
    assert parse_grid(["a.b=1,2", "c=[1,2],[3,4]"]) == {"a.b": ["1", "2"], "c": ["[1,2]", "[3,4]"]}
    for bad in (["a"], ["=1"], ["a="], ["a=1,"]):
        with pytest.raises(ConfigError, match="--grid"):
            parse_grid(bad)
    with pytest.raises(ConfigError, match="twice"):
        parse_grid(["a=1", "a=2"])
    assert (
        point_name({"controllers.0.kp": "100", "x": "[1, 2]"}) == "controllers.0.kp=100__x=_1,_2_"
    )


def _timestamps(out):
    return {
        p.parent.relative_to(out).as_posix(): json.loads(p.read_text())["finished_ns"]
        for p in out.glob("*/seed*/run.json")
    }


def test_interrupted_sweep_completes_only_missing_runs(tmp_path, monkeypatch):
    out = tmp_path / "sweep"
    grid = {"controllers.0.kp": ["100", "400"]}
    real = sweep_mod.run_job
    calls = []

    def dies_after_three(job):
        if len(calls) == 3:
            raise KeyboardInterrupt("killed")  # like a Ctrl-C / kill in the middle of the sweep
        calls.append(job.out)
        return real(job)

    monkeypatch.setattr(sweep_mod, "run_job", dies_after_three)
    with pytest.raises(KeyboardInterrupt):
        sweep(SRC, grid, seeds=3, out=out, overrides=BASE, progress=False)
    first = _timestamps(out)
    assert len(first) == 3
    assert not list(out.glob("*/.*partial*"))

    rerun = []

    def counting(job):
        rerun.append(job.out)
        return real(job)

    monkeypatch.setattr(sweep_mod, "run_job", counting)
    result = sweep(SRC, grid, seeds=3, out=out, overrides=BASE, progress=False)
    assert (result.ran, result.skipped) == (3, 3)
    assert sorted(rerun) == sorted(set(str(out / p) for p in _timestamps(out)) - set(calls))
    after = _timestamps(out)
    assert len(after) == 6
    for run, stamp in first.items():  # finished runs were not redone
        assert after[run] == stamp

    # aggregate: mean and std per grid point, recomputed from the runs' summary.json
    rows = json.loads((out / "sweep_summary.json").read_text())
    assert [r["point"] for r in rows] == [{"controllers.0.kp": "100"}, {"controllers.0.kp": "400"}]
    for row in rows:
        vals = [
            json.loads((out / point_name(row["point"]) / f"seed{s}" / "summary.json").read_text())[
                "straight.effort"
            ]
            for s in range(3)
        ]
        assert row["n_runs"] == 3
        assert row["metrics"]["straight.effort"]["mean"] == pytest.approx(np.mean(vals), rel=1e-12)
        assert row["metrics"]["straight.effort"]["std"] == pytest.approx(np.std(vals), rel=1e-12)
        assert row["metrics"]["straight.effort"]["std"] > 0  # torque noise differs by seed
    assert "straight.effort" in (out / "sweep_summary.md").read_text()

    # nothing left: a third call runs nothing
    again = sweep(SRC, grid, seeds=3, out=out, overrides=BASE, progress=False)
    assert (again.ran, again.skipped) == (0, 6)


def test_foreign_directory_is_refused(tmp_path):
    out = tmp_path / "sweep"
    sweep(SRC, {"controllers.0.kp": ["100"]}, seeds=1, out=out, overrides=BASE, progress=False)
    with pytest.raises(RunDirectoryExists, match="different sweep"):
        sweep(SRC, {"controllers.0.kp": ["200"]}, seeds=1, out=out, overrides=BASE, progress=False)
    other = tmp_path / "other"
    other.mkdir()
    (other / "file").write_text("x")
    with pytest.raises(RunDirectoryExists, match="not a sweep directory"):
        sweep(SRC, {}, seeds=1, out=other, overrides=BASE, progress=False)
    with pytest.raises(InvalidArgument, match="seeds"):
        sweep(SRC, {}, seeds=0, out=tmp_path / "z", overrides=BASE, progress=False)


@pytest.mark.slow
def test_process_pool_matches_in_process(tmp_path):
    grid = {"controllers.0.kp": ["100", "400"]}
    a = sweep(SRC, grid, seeds=1, out=tmp_path / "a", overrides=BASE, progress=False, workers=1)
    b = sweep(SRC, grid, seeds=1, out=tmp_path / "b", overrides=BASE, progress=False, workers=2)
    assert b.ran == 2
    for ra, rb in zip(a.aggregate, b.aggregate, strict=True):
        assert ra["metrics"]["straight.effort"]["mean"] == rb["metrics"]["straight.effort"]["mean"]


@pytest.mark.slow
def test_ray_local(tmp_path):
    import ray  # the distributed extra; CI installs it, so this must not be skipped

    grid = {"controllers.0.kp": ["100", "400"]}
    local = sweep(SRC, grid, seeds=1, out=tmp_path / "local", overrides=BASE, progress=False)
    res = sweep(
        SRC,
        grid,
        seeds=1,
        out=tmp_path / "ray",
        overrides=BASE,
        progress=False,
        ray_address="local",
        workers=2,
    )
    assert not ray.is_initialized()
    assert (res.ran, res.skipped) == (2, 0)
    for ra, rb in zip(local.aggregate, res.aggregate, strict=True):
        assert ra["metrics"]["straight.effort"]["mean"] == rb["metrics"]["straight.effort"]["mean"]


@pytest.mark.slow
def test_sweep_killed_by_sigterm_then_resumed(tmp_path, monkeypatch):
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    out = tmp_path / "sweep"
    script = Path(sys.executable).with_name("geosyn")
    args = [
        "sweep",
        SRC,
        "--grid",
        "controllers.0.kp=100,200,300,400",
        "--seeds",
        "2",
        "--out",
        str(out),
        "--no-progress",
    ]
    for o in [*BASE, "simulation.duration=1.0", "params.duration=1.0"]:
        args += ["--set", o]
    proc = subprocess.Popen(
        [str(script), *args],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
    )
    deadline = time.monotonic() + 120
    while len(list(out.glob("*/seed*/summary.json"))) < 2 and time.monotonic() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode != 0, f"sweep exited {proc.returncode} after SIGTERM; stderr:\n{err}"
    done = {p.parent for p in out.glob("*/seed*/summary.json")}
    assert 2 <= len(done) < 8
    assert not list(out.glob("*/.*partial*"))  # the killed run cleaned up after itself
    stamps = _timestamps(out)

    rerun = []
    real = sweep_mod.run_job
    monkeypatch.setattr(
        sweep_mod, "run_job", lambda job: (rerun.append(Path(job.out)), real(job))[1]
    )
    from geosyn.experiments.cli import main

    assert main(args) == 0
    assert sorted(rerun) == sorted({out / p for p in _timestamps(out)} - done)
    assert len(_timestamps(out)) == 8
    for run, stamp in stamps.items():
        assert _timestamps(out)[run] == stamp
    assert os.path.isfile(out / "sweep_summary.md")


def test_big_sweeps_are_refused_before_anything_runs(tmp_path, capsys, monkeypatch):
    from geosyn.experiments.cli import main

    def never(job):
        raise AssertionError("a run started")

    monkeypatch.setattr(sweep_mod, "run_job", never)
    grid = {"controllers.0.kp": [str(k) for k in range(100)], "seed": [str(s) for s in range(100)]}
    with pytest.raises(ConfigError, match=r"10000 runs .* limit of 1000; raise it with --max-runs"):
        sweep(SRC, grid, out=tmp_path / "big", overrides=BASE, progress=False)
    args = ["sweep", SRC, "--seeds", "1000000", "--out", str(tmp_path / "s"), "--no-progress"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "1000000 runs" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "s").exists() and not (tmp_path / "big").exists()
    with pytest.raises(InvalidArgument, match="max_runs"):
        sweep(SRC, {}, out=tmp_path / "x", overrides=BASE, progress=False, max_runs=0)


def test_sweep_announces_its_size(tmp_path, capsys, monkeypatch):
    sweep(SRC, {"controllers.0.kp": ["100", "400"]}, out=tmp_path / "a", overrides=BASE)
    err = capsys.readouterr().err
    assert "running 2 of 2 run(s) (2 grid point(s) x 1 seed(s); 0 already complete)" in err
    monkeypatch.setattr(sweep_mod, "run_job", lambda job: None)
    monkeypatch.setattr(sweep_mod, "load_config", lambda *a, **k: (_Cfg(), tmp_path / "x.yaml"))
    sweep(SRC, {"seed": [str(i) for i in range(60)]}, out=tmp_path / "b", progress=False)
    err = capsys.readouterr().err
    assert "60 run(s) (60 grid point(s) x 1 seed(s)); validating their configs" in err


class _Cfg:
    name = "fake"
    seed = 0


@pytest.mark.parametrize(
    "address", ["nohost", "host:", "host:0", "host:70000", "a b:1", "http://x:1", ":6379", ""]
)
def test_malformed_ray_address_is_one_error(tmp_path, address):
    with pytest.raises(ConfigError, match="--ray.*expected 'local', 'auto', HOST:PORT"):
        sweep(SRC, {}, out=tmp_path / "r", overrides=BASE, progress=False, ray_address=address)
    assert not (tmp_path / "r").exists()


def test_unreachable_ray_head_fails_fast(tmp_path):
    import socket

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(ConfigError, match=r"cannot connect within 10 s.*ray start --head"):
        sweep(
            SRC,
            {},
            out=tmp_path / "r",
            overrides=BASE,
            progress=False,
            ray_address=f"127.0.0.1:{port}",
        )


def test_ray_token_authentication_is_explained(monkeypatch):
    class AuthenticationError(Exception):
        pass

    class FakeRay:
        @staticmethod
        def init(**kwargs):
            raise AuthenticationError("Authentication failed: missing token")

    from geosyn.experiments.sweep import executors

    monkeypatch.setattr(executors, "_check_reachable", lambda address, timeout: None)
    with pytest.raises(ConfigError, match="export RAY_AUTH_MODE=token"):
        executors._ray_init(FakeRay, "127.0.0.1:6379", 1)


def test_a_second_sweep_into_a_running_one_is_refused(tmp_path):
    from geosyn.experiments.run import rundir

    out = tmp_path / "sweep"
    fd = rundir.acquire(out)
    try:
        with pytest.raises(RunDirectoryExists, match="being written by another process"):
            sweep(SRC, {}, out=out, overrides=BASE, progress=False)
    finally:
        rundir.release(out, fd)
    assert not out.exists()


def test_aggregate_excludes_and_counts_failed_runs(tmp_path):
    point = {"controllers.0.kp": "100"}
    summaries = [
        {"geodesic.ok": 1.0, "geodesic.rms_error": 0.1, "failed_runs": 0.0},
        {"geodesic.ok": 1.0, "geodesic.rms_error": 0.3, "failed_runs": 0.0},
        {"geodesic.ok": 0.0, "geodesic.rms_error": float("nan"), "failed_runs": 1.0},
    ]
    for s, summ in enumerate(summaries):
        run = tmp_path / point_name(point) / f"seed{s}"
        run.mkdir(parents=True)
        (run / "summary.json").write_text(json.dumps(summ, allow_nan=True))
    (row,) = sweep_mod.aggregate(tmp_path, [point], 3)
    assert row["n_runs"] == 3 and row["n_failed"] == 1
    rms = row["metrics"]["geodesic.rms_error"]
    assert rms["n"] == 2 and rms["mean"] == pytest.approx(0.2) and rms["std"] == pytest.approx(0.1)
    assert row["metrics"]["geodesic.ok"]["mean"] == pytest.approx(2 / 3)


def _children(pid):
    out = []
    for status in Path("/proc").glob("[0-9]*/status"):
        try:
            text = status.read_text()
        except OSError:
            continue
        if f"\nPPid:\t{pid}\n" in text:
            out.append(int(status.parent.name))
    return out


def _alive(pid):
    try:
        state = Path(f"/proc/{pid}/status").read_text().split("State:\t")[1][0]
    except (OSError, IndexError):
        return False
    return state != "Z"


def _start_long_sweep(tmp_path):
    import subprocess
    import sys

    out = tmp_path / "sweep"
    args = ["sweep", SRC, "--grid", "controllers.0.kp=100,200", "--seeds", "2"]
    args += ["--workers", "2", "--out", str(out), "--no-progress"]
    for o in [*BASE, "simulation.duration=2.0", "params.duration=2.0"]:
        args += ["--set", o]
    proc = subprocess.Popen(
        [str(Path(sys.executable).with_name("geosyn")), *args],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
    )
    return proc, out, args


def _wait_for_partials(out, proc, n=2, timeout=120.0):
    import time

    deadline = time.monotonic() + timeout
    while len(list(out.glob("*/.seed*.partial-*"))) < n and time.monotonic() < deadline:
        assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
        time.sleep(0.05)


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("signum", ["SIGKILL", "SIGTERM"])
def test_killed_sweep_leaves_no_workers_and_resumes(tmp_path, signum):
    """SIGKILL: workers die with the parent; SIGTERM: the sweep ends within seconds, its
    partial runs removed; the re-run completes only the missing runs."""
    import signal
    import time

    proc, out, args = _start_long_sweep(tmp_path)
    _wait_for_partials(out, proc)
    workers = _children(proc.pid)
    assert len(workers) >= 2
    done_at_signal = len(_timestamps(out))
    proc.send_signal(getattr(signal, signum))
    proc.communicate(timeout=60)
    # a hang guard, not a timing test: the workers are gone as soon as the kernel reaps them
    deadline = time.monotonic() + 30.0
    while any(_alive(w) for w in workers) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_alive(w) for w in workers), "worker processes outlived the sweep"
    assert proc.returncode == -signal.SIGKILL if signum == "SIGKILL" else proc.returncode == 143
    if signum == "SIGTERM":
        # no queued run starts after the signal: at most the 2 in flight complete (the
        # time to exit, ~1 s on an idle machine, within WORKER_GRACE + a kill, is a
        # figure, not a timed assertion)
        assert len(_timestamps(out)) <= done_at_signal + 2
        assert not list(out.glob("*/.*partial*")) and not list(out.glob("*/.*.lock"))
    finished = _timestamps(out)  # runs completed before the signal stay as they are

    from geosyn.experiments.cli import main

    assert main(args) == 0
    after = _timestamps(out)
    assert len(after) == 4
    for run, stamp in finished.items():
        assert after[run] == stamp
    assert not list(out.glob("*/.*partial*")) and not list(out.glob("*/.*.lock"))
    assert not list(tmp_path.glob(".*.lock"))


@pytest.mark.slow
def test_sigterm_stops_a_ray_sweep_cleanly(tmp_path):
    """Ray installs its own SIGTERM handlers (a stack dump, exit 1, or sys.exit(15)); the
    sweep keeps its own: exit 143 within seconds, tasks cancelled, then a plain re-run
    completes every run."""
    import signal
    import subprocess
    import time

    out = tmp_path / "sweep"
    args = ["sweep", SRC, "--grid", "controllers.0.kp=100,200", "--out", str(out), "--no-progress"]
    for o in [*BASE, "simulation.duration=3.0", "params.duration=3.0"]:
        args += ["--set", o]
    proc = subprocess.Popen(
        [str(Path(sys.executable).with_name("geosyn")), *args, "--ray", "local", "--workers", "2"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
    )
    deadline = time.monotonic() + 120
    while not list(out.glob("*/.seed0.partial-*")) and time.monotonic() < deadline:
        assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err[-3000:]
    # (The time to exit, ~1.3 s on an idle machine, is a figure, not a timed assertion:
    # with both cores busy by other work it took 6.8 s.)
    assert "SIGTERM received" not in err and "Traceback" not in err
    from geosyn.experiments.cli import main

    assert main(args) == 0
    assert len(_timestamps(out)) == 2
    assert not list(out.glob("*/.*partial*")) and not list(out.glob("*/.*.lock"))


# -- killed at three points, re-run: locally and on a Ray head at 127.0.0.1 ---------------
#: Kill points of a chain of interrupted sweeps: (signal, kill once at least this many of
#: the 6 runs are complete). Each chain uses both signals and three points; the two
#: executors use complementary orders, so each signal is tried at every point.
KILL_CHAINS = {
    "local": (("SIGKILL", 1), ("SIGTERM", 3), ("SIGKILL", 5)),
    "ray": (("SIGTERM", 1), ("SIGKILL", 3), ("SIGTERM", 5)),
}
_ANNOUNCE = re.compile(r"running (\d+) of (\d+) run\(s\) .*; (\d+) already complete\)")


def test_an_exported_loopback_switch_reaches_a_ray_imported_before(monkeypatch) -> None:
    """RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0 exported after Ray read it (its constant still
    on): Ray's own address resolution then still maps 127.0.0.1 to the machine's address;
    after the switch is applied it keeps 127.0.0.1 (referee: ray's resolve_ip_for_localhost)."""
    import ray._private.ray_constants as constants
    import ray._private.services as services

    from geosyn.experiments.sweep import executors

    monkeypatch.setattr(constants, "ENABLE_RAY_CLUSTER", True)
    monkeypatch.setenv("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")
    before = services.resolve_ip_for_localhost("127.0.0.1")
    executors._loopback_only_local_cluster()
    assert constants.ENABLE_RAY_CLUSTER is False
    assert services.resolve_ip_for_localhost("127.0.0.1") == "127.0.0.1"
    assert os.environ["RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"] == "0"
    print(f"\n127.0.0.1 resolved to {before} before the switch")


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def ray_head():
    """A Ray head on 127.0.0.1 (token authentication, Ray's default since 2.60) started
    with ``--block`` in its own session and stopped by signalling that session only (``ray
    stop`` would stop every Ray instance of the user on this machine). Yields the address
    and the environment a client needs."""
    import shutil
    import signal
    import subprocess
    import tempfile
    import time

    from geosyn.experiments.sweep import executors

    port = _free_port()
    # Loopback only, in the head and in this process's client whatever ran before here
    # (else Ray maps the client's 127.0.0.1 to the machine's address, which the head
    # does not listen on); `--ray local` sets the same switch.
    executors._loopback_only_local_cluster()
    # the default token (~/.ray/auth_token, created by the head if missing): a process
    # caches the token it loaded first, so an in-process client cannot switch tokens
    env = {**os.environ, "RAY_AUTH_MODE": "token"}
    temp = tempfile.mkdtemp(prefix="ray", dir="/tmp")  # short: Ray's socket paths are bounded
    cmd = [str(Path(sys.executable).with_name("ray")), "start", "--head", "--block"]
    cmd += ["--node-ip-address=127.0.0.1", f"--port={port}", "--num-cpus=2"]
    cmd += ["--include-dashboard=false", "--disable-usage-stats", f"--temp-dir={temp}"]
    cmd += [f"--dashboard-agent-listen-port={_free_port()}"]
    log = open(Path(temp) / "head.log", "w")  # noqa: SIM115 - closed in the finally
    head = subprocess.Popen(cmd, env=env, stdout=log, stderr=log, start_new_session=True)
    address = f"127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 60
        while True:
            assert head.poll() is None, (Path(temp) / "head.log").read_text()[-3000:]
            try:
                executors._check_reachable(address, 1.0)
                break
            except ConfigError:
                assert time.monotonic() < deadline, "the Ray head did not start within 60 s"
                time.sleep(0.2)
        yield address, env
    finally:
        head.send_signal(signal.SIGTERM)  # --block: its handler stops the head's processes
        try:
            head.wait(timeout=20)
        except subprocess.TimeoutExpired:
            head.kill()
        time.sleep(0.5)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(head.pid, signal.SIGKILL)  # anything of that session still running
        log.close()
        shutil.rmtree(temp, ignore_errors=True)


def _locked_runs(out: Path) -> list[Path]:
    from geosyn.experiments.run import rundir

    return [
        p.parent / p.name[1:-5]
        for p in out.glob("*/.seed*.lock")
        if rundir.is_locked(p.parent / p.name[1:-5])
    ]


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("executor", ["local", "ray"])
def test_sweep_killed_at_three_points_resumes_without_loss_or_duplicates(
    tmp_path, request, monkeypatch, executor
):
    """A sweep of 10 runs killed three times (both signals; after >= 1, 3 and 5 complete
    runs, and always after its announcement and at least one run of its own), each
    re-run announcing exactly the runs complete before it; complete runs are never redone
    (their ``finished_ns`` stamps stay) and the last re-run completes the rest. On Ray,
    the tasks of a killed driver end within 5 s (their run locks freed); a task about to
    finish may still complete its run, so a kill point never waits on a count the previous
    launch already reached."""
    import signal
    import subprocess
    import time

    env = dict(os.environ)
    extra = ["--workers", "2"]
    if executor == "ray":
        address, env = request.getfixturevalue("ray_head")
        extra += ["--ray", address]
        monkeypatch.setenv("RAY_AUTH_MODE", "token")
    out = tmp_path / "sweep"
    args = ["sweep", SRC, "--grid", "controllers.0.kp=100,200,300,400,500", "--seeds", "2"]
    args += ["--out", str(out), "--no-progress"]
    for o in [*BASE, "simulation.duration=0.6", "params.duration=0.6"]:
        args += ["--set", o]
    script = str(Path(sys.executable).with_name("geosyn"))
    total = 10
    complete: dict[str, int] = {}
    orphan_lifetimes, counts = [], []
    for signame, k in KILL_CHAINS[executor]:
        err_file = tmp_path / f"stderr-{signame}-{k}.txt"
        with open(err_file, "w") as err:
            proc = subprocess.Popen(
                [script, *args, *extra],
                stdout=subprocess.DEVNULL,
                stderr=err,
                env=env,
                cwd=tmp_path,
            )
            deadline = time.monotonic() + 120
            k_here = min(max(k, len(complete) + 1), total - 1)
            while len(_timestamps(out)) < k_here or not _ANNOUNCE.search(err_file.read_text()):
                assert proc.poll() is None, err_file.read_text()[-3000:]
                assert time.monotonic() < deadline, "no progress within 120 s"
                time.sleep(0.02)
            signum = getattr(signal, signame)
            proc.send_signal(signum)
            t0 = time.monotonic()
            proc.wait(timeout=60)
        text = err_file.read_text()
        assert proc.returncode == (-signal.SIGKILL if signame == "SIGKILL" else 143), text[-3000:]
        if signame == "SIGTERM":
            assert time.monotonic() - t0 < 5.0  # the acceptance bound; ~1 s observed
            assert "Traceback" not in text, text[-3000:]
        while _locked_runs(out) and time.monotonic() - t0 < 30:
            time.sleep(0.05)  # runs of the killed sweep still running elsewhere
        orphan_lifetimes.append(time.monotonic() - t0)
        assert not _locked_runs(out)
        # this launch saw exactly the runs complete before it, and ran only the others
        (announce,) = _ANNOUNCE.findall(text)
        assert announce == (str(total - len(complete)), str(total), str(len(complete))), announce
        now = _timestamps(out)
        for run, stamp in complete.items():  # none lost, none redone
            assert now[run] == stamp
        assert len(now) >= k
        complete = now
        counts.append(len(now))

    # the last re-run, through the Python API, completes exactly the missing runs. In a
    # fresh process: a Ray client caches the first token and address mode it saw, and a
    # pytest worker may have seen other clusters' before.
    call = f"""
import json
from geosyn.experiments.sweep import sweep
res = sweep({SRC!r}, {{"controllers.0.kp": ["100", "200", "300", "400", "500"]}}, seeds=2,
            out={str(out)!r}, overrides={[*BASE, "simulation.duration=0.6", "params.duration=0.6"]!r},
            progress=False, workers=2, ray_address={None if executor == "local" else address!r})
print(json.dumps([res.ran, res.skipped, [row["n_runs"] for row in res.aggregate]]))
"""
    done = subprocess.run(
        [sys.executable, "-c", call], env=env, cwd=tmp_path, capture_output=True, text=True,
        timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    ran, skipped, n_runs = json.loads(done.stdout.splitlines()[-1])
    assert (ran, skipped) == (total - len(complete), len(complete))
    final = _timestamps(out)
    assert len(final) == total
    for run, stamp in complete.items():
        assert final[run] == stamp
    assert n_runs == [2, 2, 2, 2, 2]
    assert not list(out.glob("*/.*partial*")) and not list(out.glob("*/.*.lock"))
    print(
        f"\n{executor}: kills {KILL_CHAINS[executor]} left {counts} of {total} runs complete; orphans gone after"
        f" {[round(x, 2) for x in orphan_lifetimes]} s"
    )
    if executor == "ray":
        assert max(orphan_lifetimes) < 5.0  # the acceptance bound; <= 0.7 s observed
