"""The GP-EKF's rows of ``gaitscope bench``: a retraining against the time it has, and against GPy as a
user would call it, measured in the same run.

Issue #11: a retrain of 5 steps must finish well within the next 5 steps. The window is the first one the
estimator offers on seed 003's protocol (:mod:`gaitscope.sessions.synth.speed_walks`, the cohort's default
subject), at the start of the sinusoid (0.8 m/s and rising). Timed:

- :func:`gaitscope.estimators.gp_models.fit_models`, as sessions run it (six FITC sparse GPs, 25 inducing points at
  training inputs, maximum likelihood, one BLAS thread, GPy's numpy kernel gradients);
- the baseline: the same six fits the way GPy's documentation writes one,
  ``GPy.models.SparseGPRegression(X, Y, num_inducing=25).optimize(max_iters=200)`` (variational DTC,
  inducing inputs optimized, the BLAS's default threads).

The budget is the walking time of the next 5 steps, which the window's own 5 steps approximate. The
per-sample cost of ``gp_ekf`` is in the per-estimator rows (``gaitscope.sessions.offline.bench.estimator_costs``).
Nothing here runs at run time.
"""

from __future__ import annotations

import time
from typing import Final

import numpy as np

from gaitscope.estimators.gp_ekf_estimator import GPEKFEstimator
from gaitscope.estimators.gp_models import TrainingWindow, fit_models
from gaitscope.estimators.protocol import input_names
from gaitscope.sessions.registry import gp_ekf_default
from gaitscope.sessions.synth.cohort import CohortSpec, make_subjects
from gaitscope.sessions.synth.speed_walks import SpeedProtocol, speed_walk

__all__ = ["first_window", "retrain_cost"]

#: Fits timed of each (the best is reported, and the median).
REPEATS: Final = 3


def first_window() -> TrainingWindow:
    """The first training window the GP-EKF offers on the protocol's walk."""
    subject = make_subjects(CohortSpec())[0]
    walk = speed_walk(subject, SpeedProtocol(walk_s=20.0, standing_s=1.0))
    est = GPEKFEstimator(*gp_ekf_default(), mass_kg=subject.mass_kg)
    z = np.column_stack([walk[c].to_numpy(np.float64) for c in input_names(est)])
    for tk, zk in zip(walk["time_s"].to_numpy(np.float64).tolist(), z, strict=True):
        est.step(tk, zk)
        window = est.take_window()
        if window is not None:
            return window
    raise RuntimeError("the walk offered no training window")


def _gpy_default(window: TrainingWindow) -> None:
    """The six fits as GPy's documentation writes a sparse GP regression."""
    import GPy

    train = ~window.heldout
    x = window.phase[train][:, None]
    for i in range(6):
        y = window.z[train, i] if i < 3 else window.z[train, i] / window.phase_rate[train]
        ok = np.isfinite(y)
        model = GPy.models.SparseGPRegression(x[ok], y[ok, None], num_inducing=25)
        model.optimize(max_iters=200)


def _times(run: object, window: TrainingWindow) -> list[float]:
    walls = []
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        run(window)  # type: ignore[operator]
        walls.append(time.perf_counter() - t0)
    return walls


def retrain_cost() -> dict[str, float]:
    """Seconds per retraining (best and median of :data:`REPEATS`), ours and GPy's default, against the
    window's 5 steps of walking."""
    window = first_window()
    fit_models(window)  # start-up: GPy imported, kernels compiled
    ours = _times(fit_models, window)
    ref = _times(_gpy_default, window)
    t0, t1 = window.span
    return {
        "samples": float(len(window.phase)),
        "steps": float(window.steps[1] - window.steps[0] + 1),
        "budget_s": t1 - t0,
        "fit_best_s": min(ours),
        "fit_median_s": float(np.median(ours)),
        "ref_best_s": min(ref),
        "ref_median_s": float(np.median(ref)),
        "ratio": float(np.median(ref) / np.median(ours)),
    }
