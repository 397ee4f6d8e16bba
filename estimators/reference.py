"""Reference phase EKF on ``filterpy.kalman.ExtendedKalmanFilter`` with plain vectorised numpy.

The same model as :class:`gaitscope.estimators.phase_ekf.PhaseEKF`, written the direct way: the measurement and
its Jacobian from the Kronecker regressor (:func:`gaitscope.estimators.basis.regressor`) and filterpy's own
predict/update. It is the oracle for the compiled filter's tests and the baseline of ``gaitscope
bench``; it is not used at run time.
"""

from __future__ import annotations

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

from gaitscope.estimators.basis import Array, regressor
from gaitscope.estimators.gait_model import NoiseModel
from gaitscope.estimators.phase_ekf import EKFConfig


class ReferencePhaseEKF:
    """filterpy-based twin of :class:`~gaitscope.estimators.phase_ekf.PhaseEKF` (same interface)."""

    def __init__(self, coef: Array, noise: NoiseModel, leg_length: float, config: EKFConfig | None = None):
        self.config = config or EKFConfig()
        self.coef = coef.reshape(coef.shape[0], -1)
        self.order = (coef.shape[-1] - 1) // 2
        self.leg_length = leg_length
        self.noise = NoiseModel(
            noise.residual_cov * self.config.measurement_noise_scale,
            noise.sensor_var * self.config.measurement_noise_scale,
        )
        self.kf = ExtendedKalmanFilter(dim_x=4, dim_z=6)
        self.kf.x = self.config.initial_state()
        self.kf.P = self.config.initial_covariance()

    @property
    def x(self) -> Array:
        return np.asarray(self.kf.x, dtype=np.float64)

    @property
    def P(self) -> Array:
        return np.asarray(self.kf.P, dtype=np.float64)

    def _terms(self, x: Array) -> tuple[Array, Array, float]:
        p, pdot, lp, r = x
        u = np.pi / 4 * lp
        l, dl = np.arctan(u) * 4 / np.pi + 2, 1 / (1 + u * u)
        P, L, R = np.array([p]), np.array([l]), np.array([r])
        # rows: h, h_p, h_pp, h_l, h_r, h_pl, h_pr; columns: outputs
        derivs = [(0, 0, 0), (1, 0, 0), (2, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, 0, 1)]
        A = np.vstack([regressor(P, L, R, self.order, dp=a, dl=b, dr=c) for a, b, c in derivs])
        return A @ self.coef.T, np.array([pdot, dl]), float(self.leg_length)

    def hx(self, x: Array) -> Array:
        t, (pdot, _), leg = self._terms(x)
        return np.array([t[0, 0], pdot * t[1, 0], t[0, 1], pdot * t[1, 1], leg * t[0, 2], leg * t[0, 3]])

    def jacobian(self, x: Array) -> Array:
        t, (pdot, dl), leg = self._terms(x)
        rows = []
        for o in (0, 1):
            rows.append([t[1, o], 0.0, t[3, o] * dl, t[4, o]])
            rows.append([pdot * t[2, o], t[1, o], pdot * t[5, o] * dl, pdot * t[6, o]])
        for o in (2, 3):
            rows.append([leg * t[1, o], 0.0, leg * t[3, o] * dl, leg * t[4, o]])
        return np.array(rows)

    def predict(self, dt: float) -> None:
        self.kf.F = np.eye(4)
        self.kf.F[0, 1] = dt
        self.kf.Q = np.diag(self.config.q_diag(dt))
        self.kf.predict()
        self.kf.x[0] %= 1.0

    def update(self, z: Array | None) -> None:
        if z is None:
            return
        ok = np.isfinite(z)
        if not ok.any():
            return
        R = self.noise.at(float(self.kf.x[0]))[np.ix_(ok, ok)]
        self.kf.dim_z = int(ok.sum())
        self.kf.update(z[ok], lambda x: self.jacobian(x)[ok], lambda x: self.hx(x)[ok], R=R)
        self.kf.x[0] %= 1.0
