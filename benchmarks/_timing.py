"""Timing helpers shared by the benchmark scripts (not part of the library)."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np


def per_call(fn: Callable[[], object], repeat: int = 7, min_time: float = 0.2) -> float:
    """Best-of-``repeat`` mean time per call [s], each repeat running >= ``min_time``."""
    fn()
    number = 1
    while True:
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        if time.perf_counter() - t0 >= min_time / 10:
            break
        number *= 2
    number = max(1, int(number * 10 * min_time / max(time.perf_counter() - t0, 1e-9) / 10))
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        best = min(best, (time.perf_counter() - t0) / number)
    return best


def samples(fn: Callable[[], object], count: int) -> np.ndarray:
    """Wall time of ``count`` individual calls [s]."""
    out = np.empty(count)
    for i in range(count):
        t0 = time.perf_counter()
        fn()
        out[i] = time.perf_counter() - t0
    return out
