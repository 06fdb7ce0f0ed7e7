"""Compiling an export with the system C compiler: shared and static library, the CMake
package config and the build rule of the closed-loop program."""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Mapping, Sequence
from pathlib import Path

from geosyn.core.codegen import LARGE_SOURCE_CHARS, LARGE_SOURCE_FLAGS
from geosyn.export.errors import ExportError

LIB_NAME = "geosyn_controller"
#: Flags of every object: hidden symbols except the C API, CasADi's exports hidden too.
BASE_FLAGS = ("-fPIC", "-fvisibility=hidden", "-DCASADI_SYMBOL_EXPORT=", "-std=c99")
OBJECT_SOURCES = ("geosyn_law.c", "geosyn_controller.c")


def find_c_compiler(compiler: str | None = None) -> str:
    """The C compiler: ``compiler`` if given, else ``cc``, else ``gcc`` on ``PATH``.

    Raises:
        ExportError: none found.
    """
    found = shutil.which(compiler) if compiler else shutil.which("cc") or shutil.which("gcc")
    if not found:
        raise ExportError(
            f"no C compiler found (asked for {compiler or 'cc or gcc'}); install one or pass"
            " compiler="
        )
    return found


#: Flags of a second build of the MPC's solver code for CPUs with AVX2 and FMA (x86-64),
#: chosen at run time by the driver (``geosyn_ddp_avx2.c`` of
#: `geosyn.controllers.mpc.ddp.native`; its fused multiply-adds
#: round differently: torques within ~1e-13 of the baseline build's).
AVX2_FLAGS = ("-mavx2", "-mfma", "-ffp-contract=fast")


def avx2_flags(compiler: str) -> tuple[str, ...]:
    """`AVX2_FLAGS` when ``compiler`` targets x86-64 and accepts them, else ``()`` (no
    second build: the library then runs the baseline build everywhere)."""
    try:
        machine = subprocess.run(
            [compiler, "-dumpmachine"], capture_output=True, text=True, check=False
        ).stdout
        if not machine.startswith("x86_64"):
            return ()
        probe = subprocess.run(
            [compiler, *AVX2_FLAGS, "-x", "c", "-c", "-", "-o", "/dev/null"],
            input="int geosyn_probe;\n", capture_output=True, text=True, check=False,
        )  # fmt: skip
    except OSError:
        return ()
    return AVX2_FLAGS if probe.returncode == 0 else ()


def run(command: Sequence[str], cwd: Path) -> None:
    """Run a build command in ``cwd``.

    Raises:
        ExportError: it could not start or exited non-zero (its stderr attached).
    """
    try:
        done = subprocess.run(list(command), cwd=cwd, capture_output=True, text=True, check=False)
    except OSError as err:
        raise ExportError(f"could not run {command[0]!r}: {err}", command) from err
    if done.returncode != 0:
        raise ExportError(
            f"{Path(command[0]).name} failed with exit status {done.returncode}:\n"
            f"{done.stderr.strip()[-2000:]}",
            command,
            done.stderr,
        )


def source_flags(
    path: Path, flags: Sequence[str], large_flags: Sequence[str] = LARGE_SOURCE_FLAGS
) -> tuple[str, ...]:
    """``flags``, or for a generated source of megabytes (the MPC's Riccati step)
    ``large_flags`` (default geosyn.core.codegen's LARGE_SOURCE_FLAGS, as the Python
    solver compiles it: a far shorter compile, slightly slower code)."""
    large = path.stat().st_size >= LARGE_SOURCE_CHARS
    return tuple(large_flags) if large else tuple(flags)


def compile_library(
    out_dir: Path,
    compiler: str,
    flags: Sequence[str],
    sources: Sequence[str] = OBJECT_SOURCES,
    large_flags: Sequence[str] = LARGE_SOURCE_FLAGS,
    extra: Mapping[str, Sequence[str]] | None = None,
) -> tuple[Path, Path]:
    """Compile ``sources`` in ``out_dir`` into ``lib{LIB_NAME}.so`` and ``.a``
    (``extra``: more flags of some sources, by name).

    Returns:
        (shared library, static library).
    """
    objects = []
    for source in sources:
        obj = Path(source).with_suffix(".o").name
        own = source_flags(out_dir / source, flags, large_flags)
        own += tuple((extra or {}).get(source, ()))
        run([compiler, *own, *BASE_FLAGS, "-c", source, "-o", obj], out_dir)
        objects.append(obj)
    shared, static = out_dir / f"lib{LIB_NAME}.so", out_dir / f"lib{LIB_NAME}.a"
    run([compiler, "-shared", "-o", shared.name, *objects, "-lm"], out_dir)
    static.unlink(missing_ok=True)
    run([shutil.which("ar") or "ar", "rcs", static.name, *objects], out_dir)
    for obj in objects:
        (out_dir / obj).unlink()
    return shared, static


def cmake_config() -> str:
    """Text of ``geosyn_controllerConfig.cmake``: imported targets
    ``geosyn_controller::shared`` and ``geosyn_controller::static`` (alias
    ``geosyn_controller::geosyn_controller`` = shared)."""
    return """\
# geosyn_controllerConfig.cmake, written by geosyn.export.
# find_package(geosyn_controller REQUIRED PATHS <export dir>)
# target_link_libraries(app PRIVATE geosyn_controller::geosyn_controller)
get_filename_component(_geosyn_dir "${CMAKE_CURRENT_LIST_FILE}" DIRECTORY)
if(NOT TARGET geosyn_controller::shared)
  add_library(geosyn_controller::shared SHARED IMPORTED)
  set_target_properties(geosyn_controller::shared PROPERTIES
    IMPORTED_LOCATION "${_geosyn_dir}/libgeosyn_controller.so"
    INTERFACE_INCLUDE_DIRECTORIES "${_geosyn_dir}")
  add_library(geosyn_controller::static STATIC IMPORTED)
  set_target_properties(geosyn_controller::static PROPERTIES
    IMPORTED_LOCATION "${_geosyn_dir}/libgeosyn_controller.a"
    INTERFACE_INCLUDE_DIRECTORIES "${_geosyn_dir}"
    INTERFACE_LINK_LIBRARIES m)
  add_library(geosyn_controller::geosyn_controller INTERFACE IMPORTED)
  set_target_properties(geosyn_controller::geosyn_controller PROPERTIES
    INTERFACE_LINK_LIBRARIES geosyn_controller::shared)
endif()
set(geosyn_controller_INCLUDE_DIRS "${_geosyn_dir}")
set(geosyn_controller_LIBRARIES geosyn_controller::geosyn_controller)
set(geosyn_controller_FOUND TRUE)
"""


def makefile(
    mujoco_dir: Path | None,
    flags: Sequence[str],
    sources: Sequence[str] = OBJECT_SOURCES,
    out_dir: Path | None = None,
    large_flags: Sequence[str] = LARGE_SOURCE_FLAGS,
    extra: Mapping[str, Sequence[str]] | None = None,
) -> str:
    """Text of the export's ``Makefile``: ``make lib`` rebuilds the libraries, ``make
    loop`` the closed-loop program against MuJoCo (``MUJOCO_DIR`` holds ``include/`` and
    ``libmujoco.so*``; default: the ``mujoco`` wheel found at export time). ``sources``:
    the library's C files; a large one in ``out_dir`` gets `source_flags`."""
    mj = str(mujoco_dir) if mujoco_dir else "/path/to/mujoco"
    cflags = " ".join([*flags, *BASE_FLAGS])
    objects = " ".join(str(Path(s).with_suffix(".o")) for s in sources)
    large = "".join(
        f"{Path(s).with_suffix('.o')}: CFLAGS = "
        f"{' '.join([*source_flags(out_dir / s, flags, large_flags), *BASE_FLAGS])}\n"
        for s in sources
        if out_dir is not None and source_flags(out_dir / s, flags, large_flags) != tuple(flags)
    )
    large += "".join(
        f"{Path(s).with_suffix('.o')}: CFLAGS += {' '.join(more)}\n"
        for s, more in (extra or {}).items()
        if more
    )
    return f"""\
# Written by geosyn.export. make lib: the libraries; make loop: the MuJoCo closed loop.
CC ?= cc
CFLAGS ?= {cflags}
MUJOCO_DIR ?= {mj}
MUJOCO_LIB ?= $(firstword $(wildcard $(MUJOCO_DIR)/libmujoco.so*) $(wildcard $(MUJOCO_DIR)/lib/libmujoco.so*))

lib: libgeosyn_controller.so libgeosyn_controller.a

%.o: %.c $(wildcard *.h)
\t$(CC) $(CFLAGS) -c $< -o $@
{large}
libgeosyn_controller.so: {objects}
\t$(CC) -shared -o $@ $^ -lm
libgeosyn_controller.a: {objects}
\tar rcs $@ $^

# The export ships the libraries without their objects: intermediate files, rebuilt only
# when a source is newer than the libraries.
.SECONDARY: {objects}

loop: loop.c libgeosyn_controller.a
\t$(CC) -O2 -std=c99 -D_POSIX_C_SOURCE=199309L -I. -I$(MUJOCO_DIR)/include loop.c \\
\t  libgeosyn_controller.a $(MUJOCO_LIB) -Wl,-rpath,$(dir $(MUJOCO_LIB)) -lm -o $@

.PHONY: lib
"""
