"""High-pass filter for heel positions (seed 000 section II-B).

``H(s) = s^2 / (s^2 + 2 zeta w s + w^2)`` with ``w = 2 pi 0.5`` rad/s and ``zeta = 0.9``, discretised by
zero-order hold. The paper discretises at ``dt = 0.01`` s; gaitscope discretises at the data's own
sample period (``dt`` argument), which equals the paper's at 100 Hz. The filter starts in the steady
state of its first input (a constant input gives zero output from the first sample), so a heel that
starts 0.9 m below the hip does not ring through the first seconds; the paper leaves the start open.

The design (:func:`design`) is SciPy's ``signal.cont2discrete(..., method="zoh")`` and ``signal.lfilter_zi``
step for step on the same numpy and ``scipy.linalg`` calls, so the coefficients are SciPy's to the bit
(``tests/estimators/test_highpass.py``) without importing ``scipy.signal`` (0.4-0.9 s, most of a short
replay's start-up: issue #24); :meth:`HighPassFilter.filter` imports it for ``lfilter``.
"""

from __future__ import annotations

import numpy as np

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
        self.b, self.a, zi_unit = design(dt, cutoff_hz, damping)
        self._zi_unit = np.ascontiguousarray(zi_unit, dtype=np.float64)
        self._zi: Array | None = None  # the state (2, c); None before the first sample

    def filter(self, x: Array) -> Array:
        """Filter a whole signal ``(n,)`` or ``(n, c)`` along axis 0, starting in steady state."""
        from scipy import signal  # here, not at import: see the module docstring

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


def design(dt: float, cutoff_hz: float = CUTOFF_HZ, damping: float = DAMPING) -> tuple[Array, Array, Array]:
    """``(b, a, zi)``: the zero-order-hold discretisation of ``H(s)`` at ``dt`` and its steady state for a
    unit input, as ``scipy.signal`` (1.17) computes them: ``cont2discrete((num, den), dt, "zoh")`` is
    ``tf2ss``, the matrix exponential of ``[[A, B], [0, 0]] dt`` and ``ss2tf``; ``lfilter_zi`` solves
    ``(I - companion(a)^T) zi = b[1:] - a[1:] b[0]``. Each line below is SciPy's on the values it would
    have (``tf2ss``'s normalisation divides by ``den[0] = 1``; ``poly`` gives ``a[0] = 1``, so
    ``lfilter_zi`` divides by nothing)."""
    from scipy import linalg

    w = 2.0 * np.pi * cutoff_hz
    num, den = np.array([[1.0, 0.0, 0.0]]), np.array([1.0, 2.0 * damping * w, w * w])
    # tf2ss: controller canonical form
    a_c = np.r_[-np.array([den[1:]]), np.eye(1, 2)]
    b_c = np.eye(2, 1)
    c_c = num[:, 1:] - np.outer(num[:, 0], den[1:])
    d_c = np.atleast_2d(num[:, 0]).reshape((1, 1))
    # cont2discrete, zoh
    em = np.vstack((np.hstack((a_c, b_c)), np.hstack((np.zeros((1, 2)), np.zeros((1, 1))))))
    ms = linalg.expm(dt * em)[:2, :]
    a_d, b_d = ms[:, 0:2], ms[:, 2:]
    # ss2tf
    a_z = np.poly(a_d)
    b_z = np.poly(a_d - np.dot(b_d, np.atleast_2d(c_c[0, :]))) + (d_c[0] - 1) * a_z
    b, a = np.asarray(b_z, dtype=np.float64).reshape(-1), np.asarray(a_z, dtype=np.float64).reshape(-1)
    # lfilter_zi
    zi = np.linalg.solve(np.eye(2) - linalg.companion(a).T, b[1:] - a[1:] * b[0])
    return b, a, zi
