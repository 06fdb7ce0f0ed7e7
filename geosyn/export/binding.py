"""Calling an exported C library from Python with ctypes (tests, benchmarks, scripts)."""

from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np

from geosyn.export.errors import ExportError

_D = ctypes.POINTER(ctypes.c_double)
_P = ctypes.c_void_p


def load_library(path: str | Path) -> ctypes.CDLL:
    """Load ``libgeosyn_controller.so`` with the argument and return types of its C API.

    Args:
        path: the shared library.

    Returns:
        The library; its functions take raw pointers (``None`` is a NULL pointer).
    """
    lib = ctypes.CDLL(str(path))
    sig = {
        "geosyn_controller_create": (_P, []),
        "geosyn_controller_destroy": (None, [_P]),
        "geosyn_controller_nq": (ctypes.c_int, [_P]),
        "geosyn_controller_reset": (ctypes.c_int, [_P, _D, _D]),
        "geosyn_controller_set_reference": (ctypes.c_int, [_P, ctypes.c_int, _D, _D, _D, _D]),
        "geosyn_controller_compute": (ctypes.c_int, [_P, ctypes.c_double, _D, _D, _D]),
        "geosyn_controller_error": (ctypes.c_char_p, [ctypes.c_int]),
    }
    for name, (restype, argtypes) in sig.items():
        fun = getattr(lib, name)
        fun.restype, fun.argtypes = restype, argtypes
    return lib


def pointer(x: np.ndarray | None) -> ctypes._Pointer[ctypes.c_double] | None:
    """A ``double*`` to a C-contiguous float64 array (``None`` stays NULL)."""
    if x is None:
        return None
    if x.dtype != np.float64 or not x.flags.c_contiguous:
        raise ExportError("arrays passed to the C library must be C-contiguous float64")
    return x.ctypes.data_as(_D)


class CController:
    """One C controller of an exported library, with numpy arguments.

    Args:
        path: ``libgeosyn_controller.so`` of an export.

    Raises:
        ExportError: ``geosyn_controller_create`` returned NULL, or (in the methods) a
            call returned an error code (its number in ``code``, its text in the message).
    """

    def __init__(self, path: str | Path) -> None:
        self.lib = load_library(path)
        self.handle = self.lib.geosyn_controller_create()
        if not self.handle:
            raise ExportError(f"geosyn_controller_create returned NULL ({path})")
        self.nq = int(self.lib.geosyn_controller_nq(self.handle))
        self._tau = np.zeros(self.nq)

    def _check(self, code: int, call: str) -> None:
        if code != 0:
            text = self.lib.geosyn_controller_error(code).decode()
            raise ExportError(f"{call}: error {code}: {text}")

    def reset(self, q: np.ndarray, v: np.ndarray) -> None:
        """``geosyn_controller_reset`` at (q (nq,) [rad], v (nq,) [rad/s])."""
        self._check(self.lib.geosyn_controller_reset(self.handle, pointer(q), pointer(v)), "reset")

    def set_reference(self, t: np.ndarray, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> None:
        """``geosyn_controller_set_reference``: t (T,) [s], q, v, a (T, nq)."""
        arrays = [np.ascontiguousarray(x, dtype=np.float64) for x in (t, q, v, a)]
        code = self.lib.geosyn_controller_set_reference(
            self.handle, int(arrays[0].size), *(pointer(x) for x in arrays)
        )
        self._check(code, "set_reference")

    def compute(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(nq,) torques [N m] (a new array) for the state at time ``t`` [s]."""
        code = self.lib.geosyn_controller_compute(
            self.handle, float(t), pointer(q), pointer(v), pointer(self._tau)
        )
        self._check(code, "compute")
        return self._tau.copy()

    def close(self) -> None:
        """``geosyn_controller_destroy`` (idempotent)."""
        if self.handle:
            self.lib.geosyn_controller_destroy(self.handle)
            self.handle = None

    def __del__(self) -> None:
        self.close()
