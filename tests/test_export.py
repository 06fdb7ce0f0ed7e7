"""geosyn.export: the exported C library, compiled with the system C compiler and loaded
with ctypes, gives the Python controllers' torques (Pinocchio's dynamics) to 1e-12
relative on the Panda and the UR5; bad input to every C function is an error code and the
controller stays usable; the library needs only libc and libm; nothing is allocated after
create (malloc, calloc, realloc wrapped by the linker); the shipped MuJoCo loop tracks as
well as geosyn's Python loop."""

from __future__ import annotations

import ctypes
import dataclasses
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from geosyn.controllers import ComputedTorque, JointTrajectoryReference, RiemannianPD
from geosyn.export import CController, ExportError, ExportResult, export_controller, load_library
from geosyn.export.binding import pointer
from geosyn.robots import load_robot
from geosyn.robots.robot import Robot
from geosyn.sim import Push, Simulation

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="needs a C compiler")

Q0 = {
    "panda": np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]),
    "ur5": np.array([0.0, -1.2, 1.4, -1.6, -1.57, 0.0]),
    "xarm7": np.array([0.0, 0.3, 0.0, 0.6, 0.0, 0.3, 0.0]),
}
GAINS = {"computed_torque": (100.0, 20.0), "riemannian_pd": (5.0, 20.0)}
RTOL = 1e-12


def make_controller(robot_name: str, kind: str) -> ComputedTorque | RiemannianPD:
    """A controller tracking a smooth 1 s joint motion (a C2 spline through 21 samples)."""
    robot = load_robot(robot_name)
    t = np.linspace(0.0, 1.0, 21)
    w = np.linspace(1.0, 2.5, robot.nv)
    ref = JointTrajectoryReference(t, Q0[robot_name] + 0.3 * np.sin(np.outer(t, w)))
    cls = ComputedTorque if kind == "computed_torque" else RiemannianPD
    return cls(robot, *GAINS[kind], reference=ref)


@pytest.fixture(scope="module")
def exports(tmp_path_factory: pytest.TempPathFactory) -> dict[tuple[str, str], ExportResult]:
    out = {}
    for robot_name in ("panda", "ur5"):
        for kind in GAINS:
            ctl = make_controller(robot_name, kind)
            path = tmp_path_factory.mktemp(f"{robot_name}_{kind}")
            out[robot_name, kind] = export_controller(
                robot_name, ctl, path, overwrite=True, sample_dt=0.02, max_samples=64
            )
    return out


def python_twin(res: ExportResult) -> ComputedTorque | RiemannianPD:
    """The Python controller tracking the reference the C library holds."""
    ctl = make_controller(res.robot, res.kind)
    ctl.set_reference(res.samples.reference())
    return ctl


def states(
    res: ExportResult, seed: int, count: int = 300
) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """Seeded (t, q, v) around the reference, before, inside and after it, some saturating."""
    rng = np.random.default_rng(seed)
    ref = res.samples.reference()
    out = []
    for t in np.sort(rng.uniform(-0.2, 1.3, count)):
        q_ref, v_ref, _ = ref.sample(float(t))
        scale = rng.choice([0.01, 0.1, 1.0])
        out.append(
            (
                float(t),
                q_ref + scale * rng.standard_normal(res.nq),
                v_ref + scale * rng.standard_normal(res.nq),
            )
        )
    return out


def assert_same_torques(c: CController, py: ComputedTorque | RiemannianPD, seq: list) -> None:
    worst = 0.0
    for t, q, v in seq:
        tau_c, tau_py = c.compute(t, q, v), py.compute(t, q, v)
        worst = max(worst, float(np.max(np.abs(tau_c - tau_py)) / np.max(np.abs(tau_py))))
    assert worst <= RTOL, worst


@pytest.mark.parametrize("robot_name", ["panda", "ur5"])
@pytest.mark.parametrize("kind", list(GAINS))
def test_torques_equal_python_controller(exports, robot_name: str, kind: str) -> None:
    """Built-in reference, then one given by set_reference at irregular times."""
    res = exports[robot_name, kind]
    c = CController(res.shared_library)
    assert c.nq == res.nq == load_robot(robot_name).nv
    py = python_twin(res)
    assert_same_torques(c, py, states(res, seed=1))
    # a new reference: 40 samples at irregular times, smooth random joint motion
    rng = np.random.default_rng(2)
    t = np.cumsum(rng.uniform(0.01, 0.05, 40)) - 0.1
    w = rng.uniform(1.0, 3.0, res.nq)
    q = Q0[robot_name] + 0.3 * np.sin(np.outer(t, w))
    v, a = 0.3 * w * np.cos(np.outer(t, w)), -0.3 * w**2 * np.sin(np.outer(t, w))
    c.set_reference(t, q, v, a)
    py.set_reference(JointTrajectoryReference(t, q, v, a))
    assert_same_torques(c, py, [(float(tk) * 1.3 - 0.05, q0, v0) for tk, q0, v0 in states(res, 3)])


def test_friction_compensation_equals_python(tmp_path: Path) -> None:
    """The xarm7's file has joint damping and dry friction: compensated by default."""
    ctl = make_controller("xarm7", "computed_torque")
    assert (
        isinstance(ctl, ComputedTorque)
        and ctl.compensate_friction
        and np.all(ctl.robot.frictionloss > 0)
    )
    res = export_controller("xarm7", ctl, tmp_path, sample_dt=0.02)
    assert "| compensate_friction | True |" in res.readme.read_text()
    assert_same_torques(CController(res.shared_library), python_twin(res), states(res, seed=4))


ARM_FIXTURE = Path(__file__).parent / "fixtures" / "arm_root_quat.xml"


def fixture_arm() -> Robot:
    """The fixture arm: viscous joint damping (0.4 and 1.5 N m s/rad), dry friction
    (0.1 N m), armature, a slide joint, three kinds of torque limit."""
    with pytest.warns(Warning):  # the file states no velocity limits (defaults, reported)
        robot = load_robot(str(ARM_FIXTURE))
    assert np.any(robot.damping) and np.any(robot.frictionloss)
    return robot


def test_riemannian_pd_with_damping_and_friction_equals_python(tmp_path: Path) -> None:
    """The PD compensates the file's damping and dry friction along v_r (D v_r +
    f_c tanh(v_r / v_s)): the C law carries both, to 1e-12; the same law without them
    differs by far more (the test can fail)."""
    robot = fixture_arm()
    t = np.linspace(0.0, 1.0, 21)
    q0 = np.array([0.3, 0.2, -0.2, 0.05, 0.3])
    ref = JointTrajectoryReference(t, q0 + 0.05 * np.sin(np.outer(t, np.linspace(1, 2.5, 5))))
    res = export_controller(robot, RiemannianPD(robot, 5.0, 20.0, reference=ref), tmp_path)
    py = RiemannianPD(robot, 5.0, 20.0, reference=res.samples.reference())
    seq = states(res, seed=5)
    assert_same_torques(CController(res.shared_library), py, seq)
    zero = np.zeros(robot.nv)
    plain_robot = dataclasses.replace(robot, damping=zero, frictionloss=zero)
    plain = RiemannianPD(plain_robot, 5.0, 20.0, reference=res.samples.reference())
    gap = max(float(np.max(np.abs(py.compute(*s) - plain.compute(*s)))) for s in seq)
    assert gap > 1e-2, gap


def test_bad_input_gives_error_codes_and_leaves_the_controller_usable(exports) -> None:
    res = exports["panda", "computed_torque"]
    lib = load_library(res.shared_library)
    h = lib.geosyn_controller_create()
    n, nan = res.nq, float("nan")
    q, v, tau = Q0["panda"].copy(), np.zeros(n), np.zeros(n)
    P = pointer

    def compute(t: float = 0.3) -> np.ndarray:
        assert lib.geosyn_controller_compute(h, t, P(q), P(v), P(tau)) == 0
        return tau.copy()

    good = compute()
    s = res.samples
    t, qs, vs, as_ = (np.ascontiguousarray(x) for x in s)
    T = t.size
    bad = {
        # compute
        "compute NULL ctl": (lib.geosyn_controller_compute(None, 0.3, P(q), P(v), P(tau)), 1),
        "compute NULL q": (lib.geosyn_controller_compute(h, 0.3, None, P(v), P(tau)), 1),
        "compute NULL v": (lib.geosyn_controller_compute(h, 0.3, P(q), None, P(tau)), 1),
        "compute NULL tau": (lib.geosyn_controller_compute(h, 0.3, P(q), P(v), None), 1),
        "compute NaN t": (lib.geosyn_controller_compute(h, nan, P(q), P(v), P(tau)), 2),
        "compute inf t": (lib.geosyn_controller_compute(h, float("inf"), P(q), P(v), P(tau)), 2),
        "compute NaN q": (
            lib.geosyn_controller_compute(h, 0.3, P(np.full(n, nan)), P(v), P(tau)),
            2,
        ),
        "compute NaN v": (
            lib.geosyn_controller_compute(h, 0.3, P(q), P(np.full(n, nan)), P(tau)),
            2,
        ),
        "compute overflow": (
            lib.geosyn_controller_compute(h, 0.3, P(q), P(np.full(n, 1e200)), P(tau)),
            5,
        ),
        # reset
        "reset NULL ctl": (lib.geosyn_controller_reset(None, P(q), P(v)), 1),
        "reset NULL q": (lib.geosyn_controller_reset(h, None, P(v)), 1),
        "reset NULL v": (lib.geosyn_controller_reset(h, P(q), None), 1),
        "reset NaN": (lib.geosyn_controller_reset(h, P(np.full(n, nan)), P(v)), 2),
        # set_reference
        "ref NULL ctl": (
            lib.geosyn_controller_set_reference(None, T, P(t), P(qs), P(vs), P(as_)),
            1,
        ),
        "ref NULL t": (lib.geosyn_controller_set_reference(h, T, None, P(qs), P(vs), P(as_)), 1),
        "ref NULL q": (lib.geosyn_controller_set_reference(h, T, P(t), None, P(vs), P(as_)), 1),
        "ref NULL v": (lib.geosyn_controller_set_reference(h, T, P(t), P(qs), None, P(as_)), 1),
        "ref NULL a": (lib.geosyn_controller_set_reference(h, T, P(t), P(qs), P(vs), None), 1),
        "ref 1 sample": (lib.geosyn_controller_set_reference(h, 1, P(t), P(qs), P(vs), P(as_)), 4),
        "ref -5 samples": (
            lib.geosyn_controller_set_reference(h, -5, P(t), P(qs), P(vs), P(as_)),
            4,
        ),
        "ref too many": (
            lib.geosyn_controller_set_reference(h, res.max_samples + 1, P(t), P(qs), P(vs), P(as_)),
            4,
        ),
        "ref time order": (
            lib.geosyn_controller_set_reference(h, T, P(t[::-1].copy()), P(qs), P(vs), P(as_)),
            3,
        ),
        "ref repeated time": (
            lib.geosyn_controller_set_reference(
                h, T, P(np.r_[t[:2], t[1:-1]]), P(qs), P(vs), P(as_)
            ),
            3,
        ),
        "ref tiny spacing": (
            lib.geosyn_controller_set_reference(
                h, T, P(np.r_[0.0, 1e-300, t[2:]]), P(qs), P(vs), P(as_)
            ),
            3,
        ),
        "ref NaN t": (
            lib.geosyn_controller_set_reference(h, T, P(np.r_[t[:-1], nan]), P(qs), P(vs), P(as_)),
            2,
        ),
        "ref NaN a": (
            lib.geosyn_controller_set_reference(
                h,
                T,
                P(t),
                P(qs),
                P(vs),
                P(np.where(np.arange(as_.size).reshape(as_.shape) == 9, nan, as_)),
            ),
            2,
        ),
    }
    wrong = {name: got for name, (got, want) in bad.items() if got != want}
    assert not wrong, wrong
    assert lib.geosyn_controller_nq(None) == -1 and lib.geosyn_controller_nq(h) == n
    texts = {code: lib.geosyn_controller_error(code).decode() for code in (*range(7), -3, 99)}
    assert len(set(texts.values())) == 8 and texts[-3] == texts[99] == "unknown error code"
    lib.geosyn_controller_destroy(None)  # a no-op
    np.testing.assert_array_equal(compute(), good)  # same reference, same torque: usable
    lib.geosyn_controller_destroy(h)


def test_library_depends_only_on_libc_and_libm(exports) -> None:
    so = exports["ur5", "riemannian_pd"].shared_library
    ldd = subprocess.run(["ldd", str(so)], capture_output=True, text=True, check=True).stdout
    print(ldd)
    libs = {line.split()[0] for line in ldd.splitlines() if line.strip()}
    allowed = ("linux-vdso.so", "libc.so", "libm.so", "/lib64/ld-linux", "ld-linux")
    assert libs and all(lib.startswith(allowed) for lib in libs), libs
    nm = subprocess.run(
        ["nm", "-D", "--undefined-only", str(so)], capture_output=True, text=True, check=True
    ).stdout
    print(nm)
    undefined = [line.split()[-1] for line in nm.splitlines() if line.strip()]
    strong = [s for s in undefined if "@" in s]
    assert strong and all("@GLIBC" in s for s in strong), undefined
    assert not [s for s in undefined if "casadi" in s or "py" in s.lower()]
    defined = subprocess.run(
        ["nm", "-D", "--defined-only", str(so)], capture_output=True, text=True, check=True
    ).stdout
    exported = {line.split()[-1] for line in defined.splitlines() if " T " in line}
    api = {
        f"geosyn_controller_{n}"
        for n in "create destroy nq reset set_reference compute error sample_reference "
        "mpc_info".split()
    }
    assert exported == api, exported


#: The allocation counter of the probes: every malloc/calloc/realloc of a program linked
#: with -Wl,--wrap=malloc,--wrap=calloc,--wrap=realloc goes through it.
ALLOC_COUNTER = r"""
#include <stdio.h>
#include <stdlib.h>
#include "geosyn_controller.h"
static long n_alloc = 0;
void* __real_malloc(size_t); void* __real_calloc(size_t, size_t); void* __real_realloc(void*, size_t);
void* __wrap_malloc(size_t n) { ++n_alloc; return __real_malloc(n); }
void* __wrap_calloc(size_t a, size_t b) { ++n_alloc; return __real_calloc(a, b); }
void* __wrap_realloc(void* p, size_t n) { ++n_alloc; return __real_realloc(p, n); }
"""

ALLOC_PROBE = r"""
int main(void) {
    geosyn_controller* c = geosyn_controller_create();
    long at_create = n_alloc;
    int n = geosyn_controller_nq(c);
    double q[64] = {0}, v[64] = {0}, tau[64], t[3] = {0.0, 0.5, 1.0}, qs[192] = {0}, z[192] = {0};
    int bad = 0;
    for (int k = 0; k < 2000; ++k) {
        q[k % n] = 0.001 * k;
        bad += geosyn_controller_compute(c, 0.001 * k - 0.5, q, v, tau) != 0;
        if (k % 100 == 0) {
            bad += geosyn_controller_reset(c, q, v) != 0;
            bad += geosyn_controller_set_reference(c, 3, t, qs, z, z) != 0;
            bad += geosyn_controller_set_reference(c, 3, t, NULL, z, z) == 0;
            geosyn_controller_error(k);
        }
    }
    printf("allocations_in_create %ld\nallocations_after_create %ld\nfailed_calls %d\n",
           at_create, n_alloc - at_create, bad);
    geosyn_controller_destroy(c);
    return 0;
}
"""


def count_allocations(res: ExportResult, main_c: str, tmp_path: Path) -> dict[str, int]:
    """Compile ``ALLOC_COUNTER + main_c`` against an export's static library with every
    allocation wrapped, run it, and return the ``name count`` lines it prints."""
    (tmp_path / "probe.c").write_text(ALLOC_COUNTER + main_c)
    exe = tmp_path / "probe"
    wrap = "-Wl,--wrap=malloc,--wrap=calloc,--wrap=realloc"
    subprocess.run(
        ["nice", "-n", "10", "cc", "-O2", f"-I{res.out_dir}", str(tmp_path / "probe.c"),
         str(res.static_library), wrap, "-lm", "-o", str(exe)],
        check=True,
    )  # fmt: skip
    out = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout
    print(out)
    return {name: int(value) for name, value in (line.split() for line in out.splitlines())}


def test_no_heap_allocation_after_create(exports, tmp_path: Path) -> None:
    """The static library linked with -Wl,--wrap=malloc,--wrap=calloc,--wrap=realloc: every
    allocation of the library goes through a counter."""
    counts = count_allocations(exports["panda", "riemannian_pd"], ALLOC_PROBE, tmp_path)
    assert counts["allocations_in_create"] >= 1  # the counter sees the library's calloc
    assert counts["allocations_after_create"] == 0
    assert counts["failed_calls"] == 0


def test_export_refuses_what_it_cannot_do(exports, tmp_path: Path) -> None:
    res = exports["panda", "computed_torque"]
    with pytest.raises(ExportError, match="not empty"):
        export_controller("panda", make_controller("panda", "computed_torque"), res.out_dir)
    with pytest.raises(ExportError, match="max_samples"):
        export_controller(
            "panda", make_controller("panda", "computed_torque"), tmp_path / "a", max_samples=10
        )
    with pytest.raises(ExportError, match="not the controller's robot"):
        export_controller("ur5", make_controller("panda", "computed_torque"), tmp_path / "b")

    class Other(ComputedTorque):
        pass

    ctl = make_controller("panda", "computed_torque")
    ctl.__class__ = Other
    with pytest.raises(ExportError, match="cannot be exported"):
        export_controller("panda", ctl, tmp_path / "c")
    readme = res.readme.read_text()
    assert "| kp [1/s^2] | [100.0," in readme and "interpolation error" in readme
    assert ctypes.sizeof(ctypes.c_double) == 8


def run_loop(res: ExportResult, duration: float, force: float) -> dict[str, float]:
    subprocess.run(["nice", "-n", "10", "make", "-s", "loop"], cwd=res.out_dir, check=True)
    args = [str(duration), str(force), str(res.push.start), str(res.push.length)]
    done = subprocess.run(
        [str(res.out_dir / "loop"), str(res.model_xml), *args],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    print(done.stdout)
    return {k: float(v) for k, v in (line.split() for line in done.stdout.splitlines())}


def test_c_loop_tracks_as_well_as_the_python_loop(exports) -> None:
    """loop.c (MuJoCo's C library, 1 kHz, a 60 N push) against geosyn.sim.Simulation with
    the Python controller on the same MJCF, reference and push: the same RMS error."""
    res = exports["panda", "computed_torque"]
    duration, force = 1.2, 60.0
    c = run_loop(res, duration, force)
    push = Push(
        res.push.body, [force * d for d in res.push.direction], res.push.start, res.push.length
    )
    py = Simulation(load_robot("panda"), python_twin(res), disturbances=[push])
    log = py.run(res.samples.q[0], duration=duration, reference=res.samples.reference())
    rms_py = log.rms_error()
    print(f"rms C {c['rms_error_rad']:.6g} rad, Python {rms_py:.6g} rad")
    assert c["ticks"] == round(duration / 1e-3)
    assert rms_py > 1e-3  # the push moves the arm: the comparison is not of two zeros
    assert c["rms_error_rad"] <= 1.01 * rms_py
    assert abs(c["rms_error_rad"] - rms_py) <= 1e-3 * rms_py  # same loop, same physics
    assert 0.0 < c["tick_median_us"] <= c["tick_p99_us"] <= c["tick_max_us"]
