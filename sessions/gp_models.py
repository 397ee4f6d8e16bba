"""Seed 003's GP-EKF model versions as a recording holds them (``/gp_models``,
:class:`~gaitscope.sessions.schema.GPModelRecord`), and their replay in a review re-run.

Live (:mod:`gaitscope.sessions.live.gp_learning`) the GP-EKF retrains in the background and installs each accepted
version at a heel strike; every version is recorded with its arrays (``trained``, ``refused``; ``kept`` at a
recording's start for those from before it) and every install with its heel strike's time (``installed``).
A re-run (:mod:`gaitscope.sessions.review.rerun`) does not retrain: :class:`GPReplay` installs the recorded versions at
the recorded heel strikes, so the re-run's ``gp_ekf`` outputs are those that ran live, as
:mod:`gaitscope.sessions.imu_calibration` re-applies a recorded IMU calibration.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Final

import numpy as np

from gaitscope.estimators.gp_ekf_estimator import GPEKFEstimator
from gaitscope.estimators.gp_models import CHANNEL_NAMES, GPModelSet
from gaitscope.sessions import schema
from gaitscope.sessions.stack import EstimatorStack

__all__ = ["GP_EKF", "GPReplay", "arrays_of", "gp_ekf_of", "models_of", "rmse_of", "window_text"]

#: The GP-EKF's name in a stack (``gaitscope.sessions.registry.ESTIMATORS``).
GP_EKF: Final = "gp_ekf"


def gp_ekf_of(stack: EstimatorStack) -> GPEKFEstimator | None:
    """The stack's GP-EKF (None: it runs none)."""
    return next((e for e in stack.estimators if isinstance(e, GPEKFEstimator)), None)


def arrays_of(models: GPModelSet) -> dict[str, schema.GPArray]:
    """A model set's arrays (:meth:`~gaitscope.estimators.gp_models.GPModelSet.to_arrays`) as a record holds them."""
    return {
        k: schema.GPArray(shape=list(a.shape), values=np.asarray(a, dtype=np.float64).ravel().tolist())
        for k, a in models.to_arrays().items()
    }


def models_of(arrays: Mapping[str, schema.GPArray]) -> GPModelSet:
    """The model set of a record's arrays, bit for bit the one recorded (without its training window).

    Raises:
        ValueError: an array is missing or its values do not fill its shape.
    """
    try:
        return GPModelSet.from_arrays(
            {k: np.array(a.values, dtype=np.float64).reshape(a.shape) for k, a in arrays.items()}
        )
    except KeyError as e:
        raise ValueError(f"the model set has no array {e}") from None


def rmse_of(rmse: Iterable[float]) -> dict[str, float | None]:
    """Held-out RMSE per channel (``hip angle``, ..., ``ankle velocity``) as a record holds it (NaN: None)."""
    return {name: float(v) if math.isfinite(v) else None for name, v in zip(CHANNEL_NAMES, rmse, strict=True)}


def window_text(version: int, steps: tuple[int, int], span: tuple[float, float]) -> str:
    """``GP model v3 trained on steps 11-15 (12.1-17.4 s)``."""
    return f"GP model v{version} trained on steps {steps[0]}-{steps[1]} ({span[0]:.1f}-{span[1]:.1f} s)"


class GPReplay:
    """What a recording says the GP-EKF installed live, installed again at the same heel strikes.

    Feed it the recording's ``/gp_models`` records (:meth:`add`, all of them before the first frame: an
    install is recorded after the heel strike it happened at), then call :meth:`before` before stepping each
    frame: a recorded install due at that frame's time is scheduled on the filter, which installs it at the
    heel strike of that frame, as live. A ``kept`` record marked ``current`` (a recording started while a
    retrained version ran) is installed at the first heel strike: the re-run starts from the population
    model, so until then it differs from what ran.
    """

    def __init__(self) -> None:
        self.versions: dict[int, GPModelSet] = {}
        self.installs: list[tuple[float, int]] = []
        self.missing: set[int] = set()  #: installed versions without recorded arrays (not replayed)
        self._next = 0

    def add(self, record: schema.GPModelRecord) -> None:
        """One ``/gp_models`` record, in file order.

        Raises:
            ValueError: its arrays do not make a model set.
        """
        if record.arrays is not None and record.version is not None:
            self.versions[record.version] = models_of(record.arrays)
        if record.version is None:
            return
        if record.what == "installed":
            self.installs.append((record.t, record.version))
        elif record.what == "kept" and record.current:
            self.installs.append((-math.inf, record.version))
        self.installs.sort(key=lambda i: i[0])

    @property
    def active(self) -> bool:
        """There are installs left to replay."""
        return self._next < len(self.installs)

    def before(self, estimator: GPEKFEstimator, t: float, period: float) -> None:
        """Schedule the installs due at the frame at session time ``t`` (within half a sample ``period``)."""
        while self._next < len(self.installs) and self.installs[self._next][0] <= t + 0.5 * period:
            version = self.installs[self._next][1]
            self._next += 1
            f = estimator.filter
            models = self.versions.get(version, f.initial if version == f.initial.version else None)
            if models is None:
                self.missing.add(version)
                continue
            f.install_next(models)
