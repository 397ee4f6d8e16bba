"""High-pass filter for heel positions (seed 000 section II-B).

``H(s) = s^2 / (s^2 + 2 zeta w s + w^2)`` with ``w = 2 pi 0.5`` rad/s and ``zeta = 0.9``, discretised by
zero-order hold. The paper discretises at ``dt = 0.01`` s; gaitscope discretises at the data's own
sample period (``dt`` argument), which equals the paper's at 100 Hz. The filter starts in the steady
state of its first input (a constant input gives zero output from the first sample), so a heel that
starts 0.9 m below the hip does not ring through the first seconds; the paper leaves the start open.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from gaitscope.estimators import _kernels
from gaitscope.estimators.basis import Array

CUTOFF_HZ = 0.5
DAMPING = 0.9


class HighPassFilter:
    """Second-order high-pass, vectorised over channels.

    Args:
        dt: sample period (s).
        cutoff_hz, damping: ``w = 2 pi cutoff_hz``, ``zeta``.
    """

    def __init__(self, dt: float, cutoff_hz: float = CUTOFF_HZ, damping: float = DAMPING):
        if not dt > 0:
            raise ValueError(f"dt must be positive, got {dt}")
        w = 2.0 * np.pi * cutoff_hz
        num, den = [1.0, 0.0, 0.0], [1.0, 2.0 * damping * w, w * w]
        bz, az, _ = signal.cont2discrete((num, den), dt, method="zoh")
        self.b = np.asarray(bz, dtype=np.float64).reshape(-1)
        self.a = np.asarray(az, dtype=np.float64).reshape(-1)
        self._zi_unit = np.ascontiguousarray(signal.lfilter_zi(self.b, self.a), dtype=np.float64)
        self._zi: Array | None = None  # the state (2, c); None before the first sample

    def filter(self, x: Array) -> Array:
        """Filter a whole signal ``(n,)`` or ``(n, c)`` along axis 0, starting in steady state."""
        x = np.asarray(x, dtype=np.float64)
        zi = self._zi_unit.reshape((-1,) + (1,) * (x.ndim - 1)) * x[0]
        return signal.lfilter(self.b, self.a, x, axis=0, zi=zi)[0]

    def step(self, x: Array) -> Array:
        """Filter one sample ``(c,)`` of a stream (direct form II transposed); returns the output.

        A sample holding a non-finite value is returned unfiltered and does not move the filter; one
        whose output would not be finite restarts the filter in its steady state (see
        :func:`gaitscope.estimators._kernels.highpass_step`, which does the work, compiled).
        """
        out = np.array(x, dtype=np.float64).reshape(-1)
        self.step_inplace(out)
        return out

    def step_inplace(self, x: Array) -> None:
        """:meth:`step` writing the output over ``x``, a C-contiguous float64 ``(c,)`` (a view is fine)."""
        zi = self._zi
        started = zi is not None
        if zi is None:
            zi = np.zeros((2, x.shape[0]))
        if _kernels.highpass_step(self.b, self.a, self._zi_unit, zi, started, x):
            self._zi = zi
        else:
            self._zi = None
