"""Timing one estimator's ``step`` sample by sample, for the benchmarks (nothing here runs at run time)."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

__all__ = ["step_times"]


def step_times(
    step: Callable[[float, NDArray[np.float64]], object], t: list[float], z: NDArray[np.float64]
) -> NDArray[np.int64]:
    """Nanoseconds of each ``step(t[k], z[k])``, with nothing else between the clock reads."""
    ns = np.empty(len(t), dtype=np.int64)
    clock = time.perf_counter_ns
    for k, tk in enumerate(t):
        zk = z[k]
        t0 = clock()
        step(tk, zk)
        ns[k] = clock() - t0
    return ns
