"""pygeodex's side of `benchmarks/planning.py`, through its own venv (`geodex_runner.py`):
running the runner, and checking that geodex's Panda is geosyn's (mass matrix, joint
order and limits, collision spheres in geosyn's joint frames)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from geosyn.robots import CollisionSphere, Robot

ROOT = Path(__file__).resolve().parent.parent
RUNNER = Path(__file__).resolve().parent / "geodex_runner.py"
GEODEX_PYTHON = Path(os.environ.get("GEODEX_PYTHON", ROOT / ".venv-geodex" / "bin" / "python"))


def geodex_run(*args: str) -> None:
    """Run ``geodex_runner.py`` with ``args`` in the geodex venv; raise with its stderr."""
    if not GEODEX_PYTHON.exists():
        raise SystemExit(
            f"geodex venv not found at {GEODEX_PYTHON}: run `bash benchmarks/setup_geodex.sh` "
            "(or set GEODEX_PYTHON to a Python >= 3.12 with pygeodex installed)"
        )
    proc = subprocess.run([str(GEODEX_PYTHON), str(RUNNER), *args], capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"geodex_runner {args[0]} failed:\n{proc.stderr}")


class MassMatrixCheck(NamedTuple):
    """geosyn's M(q) (pin.crba) vs geodex's ``mass_matrix(q)`` at seeded configurations."""

    samples: int
    max_abs: float  # max |M_ij - Mg_ij| [kg m^2]
    max_rel_frobenius: float  # max ||M - Mg||_F / ||M||_F
    max_rel_quadratic: float  # max over q, v of |v^T (Mg - M) v| / v^T M v
    same_joint_order: bool
    max_limit_difference: float  # [rad]


def check_mass_matrix(
    robot: Robot, workdir: Path, samples: int = 20, seed: int = 0
) -> MassMatrixCheck:
    """Compare M(q) of ``robot`` with geodex's Panda at ``samples`` seeded random q."""
    import scipy.linalg

    rng = np.random.default_rng(seed)
    Q = np.stack([robot.random_q(rng) for _ in range(samples)])
    np.savez(workdir / "q.npz", q=Q)
    geodex_run("mass-matrix", "--q", str(workdir / "q.npz"), "--out", str(workdir / "M.npz"))
    out = np.load(workdir / "M.npz")
    data = robot.model.createData()
    abs_, fro, quad = [], [], []
    for q, Mg in zip(Q, out["M"], strict=True):
        M = pin.crba(robot.model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        abs_.append(np.abs(M - Mg).max())
        fro.append(np.linalg.norm(M - Mg) / np.linalg.norm(M))
        quad.append(np.abs(scipy.linalg.eigh(Mg - M, M, eigvals_only=True)).max())
    names = [str(n) for n in out["joint_names"]]
    limits = max(np.abs(out["lower"] - robot.q_min).max(), np.abs(out["upper"] - robot.q_max).max())
    return MassMatrixCheck(
        samples, max(abs_), max(fro), max(quad), names == list(robot.joint_names), float(limits)
    )


def geodex_sphere_model(robot: Robot, workdir: Path, samples: int = 6, seed: int = 1):
    """geodex's (VAMP) collision spheres as geosyn `CollisionSphere`s in joint frames.

    geodex reports its spheres in the world at a configuration; each is rigidly attached
    to one link, so its coordinates in that link's joint frame (geosyn's kinematics) are
    the same at every q. Each sphere goes to the joint frame where they vary least over
    ``samples`` seeded configurations.

    Returns:
        (spheres, residual): the spheres and the largest variation of an assigned sphere's
        local coordinates [m] (~1e-7 m: geodex's float32; larger means the two kinematic
        models differ).
    """
    rng = np.random.default_rng(seed)
    Q = np.stack([robot.random_q(rng) for _ in range(samples)])
    np.savez(workdir / "qs.npz", q=Q)
    geodex_run("spheres", "--q", str(workdir / "qs.npz"), "--out", str(workdir / "S.npz"))
    S = np.load(workdir / "S.npz")["spheres"]  # (samples, n_spheres, 4)
    model, data = robot.model, robot.model.createData()
    local = np.zeros((samples, model.njoints, S.shape[1], 3))
    for k, q in enumerate(Q):
        pin.forwardKinematics(model, data, q)
        for j in range(model.njoints):
            T = data.oMi[j]
            local[k, j] = (S[k, :, :3] - T.translation) @ T.rotation
    spread = local.std(axis=0).max(axis=-1)  # (njoints, n_spheres)
    joint = spread.argmin(axis=0)
    residual = float(spread[joint, np.arange(S.shape[1])].max())
    spheres = tuple(
        CollisionSphere(
            str(model.names[int(j)]),
            tuple(float(c) for c in local[:, j, i].mean(axis=0)),
            float(S[0, i, 3]),
        )
        for i, j in enumerate(joint)
    )
    return spheres, residual
