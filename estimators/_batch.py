"""The seed-000 pipeline over a whole trial in one compiled call. Private: use
:meth:`gaitscope.estimators.pipeline.GaitStatePipeline.run`.

:func:`run` does, sample after sample, exactly what :meth:`GaitStatePipeline.step` does (plausibility
screening, heel high-pass, heel-strike detection, EKF predict and update, heel-strike backup, TBE,
filter health check and divergence reset, gap restart, torque), with the same compiled kernels of
:mod:`gaitscope.estimators._kernels` and the same floating-point operations in the same order, so its outputs
are the streaming ones (``tests/estimators/test_batch.py`` asserts 1e-12; they are equal bit for bit).
Every branch is compiled, the rare ones (gap restart, divergence reset, a backup reset to its start)
included: there is no fallback to ``step``. A pipeline's whole state goes in and comes back, so a trial
may be cut anywhere between :meth:`run` and :meth:`step` calls.

Differences from calling ``step`` in a loop: the whole input is checked first (times finite and
increasing, shapes), so a bad time raises before any sample is processed, not at its sample; the
per-sample ``GaitEstimate`` objects are replaced by arrays.

Layout: the constants of a run travel as one named tuple (:class:`_Params`); the scalar state as two
flat arrays, float and integer, indexed by the ``_F_*`` and ``_I_*`` names below; the filters' own
arrays are passed as they are and updated in place. The Python objects' attributes stay the
source of truth: :func:`run` reads them before the loop and writes them back after it.

numba keys a function's on-disk cache on its own source file only, but the functions here compile
those of :mod:`gaitscope.estimators._kernels` into themselves: :class:`_KernelsStampedLocator` adds
``_kernels.py`` to this module's cache stamp, so that an edit there recompiles the batch too.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numba import config as numba_config
from numba import njit
from numba.core.caching import CacheImpl, InTreeCacheLocator
from numpy.typing import NDArray

from gaitscope.estimators import _kernels
from gaitscope.estimators.basis import Array
from gaitscope.estimators.gait_model import N_CHANNELS

if TYPE_CHECKING:
    from gaitscope.estimators.pipeline import GaitStatePipeline

__all__ = ["FAULTS", "State", "run", "state", "step", "store"]


#: The modules beside this one whose compiled functions compile those of other files into themselves, and
#: those files: this one (``_kernels.py``) and the supervised replay's (:mod:`gaitscope.estimators._lock_batch`).
_COMPILED_IN = {"_batch.py": ("_kernels.py",), "_lock_batch.py": ("_kernels.py", "_batch.py")}


class _KernelsStampedLocator(InTreeCacheLocator):
    """numba's cache beside the source (``__pycache__``), for the modules of :data:`_COMPILED_IN` only, stamped
    with the contents of the files they compile in as well as of their own. With ``NUMBA_CACHE_DIR`` set or a
    read-only folder numba's own locators apply (then delete ``_batch*`` and ``_lock_batch*`` from the cache
    after editing ``_kernels.py`` or ``_batch.py``)."""

    @classmethod
    def from_function(cls, py_func: Any, py_file: str) -> Any:
        path = Path(py_file).resolve()
        if getattr(numba_config, "CACHE_DIR", "") or path.parent != Path(__file__).resolve().parent:
            return None
        if path.name not in _COMPILED_IN:
            return None
        return super().from_function(py_func, py_file)

    def get_source_stamp(self) -> Any:
        here = Path(__file__).resolve().parent
        names = _COMPILED_IN[Path(self._py_file).name]
        return (super().get_source_stamp(), *(hashlib.sha256((here / n).read_bytes()).digest() for n in names))


CacheImpl._locator_classes.insert(0, _KernelsStampedLocator)

#: The ``fault`` values of :meth:`GaitStatePipeline.run`; the compiled loop writes their index.
FAULTS = ("", "gap", "diverged", "torque")
_OK, _GAP, _DIVERGED, _TORQUE = range(len(FAULTS))

# float state: last time; backup; TBE; detector; the EKF's last likelihood terms; the heel positions' settling
# after a restart (GaitStatePipeline._heel_settle, _heel_masked_until)
(
    _F_T, _F_BK_PHASE, _F_BK_RATE, _F_BK_SSE_EKF, _F_BK_SSE_HP, _F_BK_LAST_HS, _F_TBE_PERIOD, _F_TBE_T,
    _F_TBE_LAST_HS, _F_TBE_MIN, _F_TBE_MAX, _F_DET_LAST_HS, _F_DET_PREV_VEL, _F_LOG_LIKELIHOOD, _F_MAHALANOBIS,
    _F_HEEL_SETTLE, _F_HEEL_MASKED_UNTIL,
) = range(17)  # fmt: skip
# integer state: flags and counters
(
    _I_HAS_T, _I_IMPLAUSIBLE, _I_RESTARTS, _I_RESETS, _I_BK_RESETS, _I_BK_HAS_LAST_HS, _I_TBE_SEEN_HS,
    _I_HP_STARTED, _I_ACCEL_BLOCKED,
) = range(9)  # fmt: skip
_FROZEN = 1e-20  # gaitscope.estimators.phase_ekf.FROZEN_VARIANCE


class _Params(NamedTuple):
    """The constants of one run: configuration, and what a restart starts from."""

    max_gap_s: float
    q_var: tuple[float, float, float]  # EKFConfig.q_std squared
    q_time_unit: float
    process_noise_scale: float
    no_task: bool
    ekf_leg_length: float
    log_2pi: float
    use_backup: bool
    backup_q_rate: tuple[float, float]
    sse_margin: float
    reset_p: float
    backup_min_period: float
    backup_max_period: float
    backup_initial_period: float
    backup_p0: float
    detect: bool
    max_foot_angle_deg: float
    refractory_s: float
    accel_threshold_set: bool
    heel_filtered: bool
    min_phase_rate: float
    max_phase_rate: float
    max_abs_incline: float
    max_variance: float
    torque_scale: float
    cutoff_phase: float
    mass_times_gain: float
    max_torque: float
    leg_length: float
    tbe_initial_period: float  # of a new TimingBasedEstimator()
    tbe_min_period: float
    tbe_max_period: float


@njit(cache=True)
def _tbe_refresh(fs: Array, tbe_x: Array) -> None:
    """``TimingBasedEstimator._refresh``."""
    tbe_x[0] = ((fs[_F_TBE_T] - fs[_F_TBE_LAST_HS]) / fs[_F_TBE_PERIOD]) % 1.0
    tbe_x[1] = 1.0 / fs[_F_TBE_PERIOD]


@njit(cache=True)
def _new_backup(prm: _Params, fs: Array, ns: NDArray[np.int64], x0: Array, bk_x: Array, bk_P: Array) -> None:
    """``HeelStrikeBackup(ekf, noise, config)``: from the EKF's initial stride length and incline."""
    bk_x[0], bk_x[1] = x0[2], x0[3]
    bk_P[:] = 0.0
    bk_P[0, 0] = bk_P[1, 1] = prm.backup_p0
    fs[_F_BK_PHASE] = 0.0
    fs[_F_BK_RATE] = 1.0 / prm.backup_initial_period
    fs[_F_BK_SSE_EKF] = fs[_F_BK_SSE_HP] = 0.0
    ns[_I_BK_RESETS] = ns[_I_BK_HAS_LAST_HS] = 0


@njit(cache=True)
def _restart(prm: _Params, fs: Array, ns: NDArray[np.int64], start: tuple, ekf: tuple, bk: tuple, tbe_x: Array) -> None:
    """``GaitStatePipeline._start_filters``: every filter in its initial state."""
    x0, P0 = start[0], start[1]
    ekf_x, ekf_P, ekf_y, ekf_S, ekf_K, ekf_zpred, ekf_H, ekf_R = ekf
    ekf_x[:] = x0
    ekf_P[:] = P0
    ekf_y[:] = np.nan
    ekf_S[:] = np.nan
    ekf_K[:] = np.nan
    ekf_zpred[:] = 0.0
    ekf_H[:] = 0.0
    ekf_R[:] = 0.0
    fs[_F_LOG_LIKELIHOOD] = fs[_F_MAHALANOBIS] = 0.0
    if prm.use_backup:
        _new_backup(prm, fs, ns, x0, bk[0], bk[1])
    fs[_F_TBE_PERIOD], fs[_F_TBE_T], fs[_F_TBE_LAST_HS] = prm.tbe_initial_period, 0.0, 0.0
    fs[_F_TBE_MIN], fs[_F_TBE_MAX] = prm.tbe_min_period, prm.tbe_max_period
    ns[_I_TBE_SEEN_HS] = 0
    tbe_x[0], tbe_x[1] = 0.0, 1.0 / prm.tbe_initial_period
    fs[_F_DET_LAST_HS], fs[_F_DET_PREV_VEL] = -np.inf, np.nan
    ns[_I_ACCEL_BLOCKED] = prm.accel_threshold_set  # a new detector has no acceleration history
    ns[_I_HP_STARTED] = 0


@njit(cache=True)
def _detect(prm: _Params, fs: Array, ns: NDArray[np.int64], t: float, angle: float, vel: float) -> bool:
    """``HeelStrikeDetector.detect`` as the pipeline calls it (no heel positions)."""
    turned = fs[_F_DET_PREV_VEL] >= 0.0 and vel < 0.0
    fs[_F_DET_PREV_VEL] = vel
    if not turned or not 0.0 < angle <= prm.max_foot_angle_deg:
        return False
    if t - fs[_F_DET_LAST_HS] <= prm.refractory_s:
        return False
    if ns[_I_ACCEL_BLOCKED]:
        return False
    fs[_F_DET_LAST_HS] = t
    return True


@njit(cache=True)
def _ekf_reset(ekf_x: Array, ekf_P: Array, x: Array, P: Array) -> None:
    """``PhaseEKF.reset``."""
    ekf_x[:] = x
    ekf_x[0] %= 1.0
    ekf_P[:] = P


@njit(cache=True)
def _sse(y: Array, R: Array, R_L: Array, all_used: NDArray[np.bool_]) -> float:
    """``_kernels.weighted_sse(y, R)``, with R's factor ``R_L`` computed once for when all of y is there."""
    for a in range(N_CHANNELS):
        if not np.isfinite(y[a]):
            return _kernels.weighted_sse(y, R)
    return _kernels.whitened_sse(R_L, y, all_used)


@njit(cache=True)
def _backup_track(
    prm: _Params,
    fs: Array,
    ns: NDArray[np.int64],
    t: float,
    dt: float,
    z: Array,
    hs: bool,
    model: tuple,
    ekf: tuple,
    bk: tuple,
    work: tuple,
) -> bool:
    """``HeelStrikeBackup.track`` beside the main EKF; True if it reset the EKF."""
    coef, rbar, rbar_L = model[0], model[2], model[3]
    ekf_x, ekf_P, ekf_y, ekf_R = ekf[0], ekf[1], ekf[2], ekf[7]
    bk_x, bk_P, bk_y, bk_S, bk_K = bk
    terms, x4, h, H, H2, all_used = work
    if hs:
        if ns[_I_BK_HAS_LAST_HS]:
            period = t - fs[_F_BK_LAST_HS]
            if prm.backup_min_period <= period <= prm.backup_max_period:
                fs[_F_BK_RATE] = 1.0 / period
        fs[_F_BK_LAST_HS] = t
        ns[_I_BK_HAS_LAST_HS] = 1
        fs[_F_BK_PHASE] = 0.0
    else:
        fs[_F_BK_PHASE] = (fs[_F_BK_PHASE] + fs[_F_BK_RATE] * dt) % 1.0
    bk_P[0, 0] += prm.backup_q_rate[0] * dt
    bk_P[1, 1] += prm.backup_q_rate[1] * dt
    x4[0], x4[1], x4[2], x4[3] = fs[_F_BK_PHASE], fs[_F_BK_RATE], bk_x[0], bk_x[1]
    _kernels.measurement(coef, x4, prm.ekf_leg_length, terms, h, H, False)  # H[:, 2:4] only
    for i in range(N_CHANNELS):
        H2[i, 0], H2[i, 1] = H[i, 2], H[i, 3]
    _kernels.update(bk_x, bk_P, z, h, H2, ekf_R, bk_y, bk_S, bk_K, False)
    fs[_F_BK_SSE_HP] += _sse(bk_y, rbar, rbar_L, all_used)
    fs[_F_BK_SSE_EKF] += _sse(ekf_y, rbar, rbar_L, all_used)
    reset = False
    if hs:
        if fs[_F_BK_SSE_EKF] - fs[_F_BK_SSE_HP] > prm.sse_margin:
            x4[0], x4[1], x4[2], x4[3] = fs[_F_BK_PHASE], fs[_F_BK_RATE], bk_x[0], bk_x[1]
            _ekf_reset(ekf_x, ekf_P, x4, prm.reset_p * np.eye(4))
            ns[_I_BK_RESETS] += 1
            reset = True
        fs[_F_BK_SSE_EKF] = fs[_F_BK_SSE_HP] = 0.0
    return reset


@njit(cache=True)
def _reset_diverged(
    prm: _Params, fs: Array, ns: NDArray[np.int64], start: tuple, ekf: tuple, bk: tuple, tbe_x: Array
) -> None:
    """``GaitStatePipeline._reset_diverged``: from the backup, else the TBE, else the initial state."""
    x0, P0 = start[0], start[1]
    ekf_x, ekf_P = ekf[0], ekf[1]
    bk_x, bk_P = bk[0], bk[1]
    ns[_I_RESETS] += 1
    candidates = np.empty((2, 4))
    n = 0
    if prm.use_backup:
        candidates[0, 0], candidates[0, 1] = fs[_F_BK_PHASE], fs[_F_BK_RATE]
        candidates[0, 2], candidates[0, 3] = bk_x[0], bk_x[1]
        n = 1
    candidates[n, 0], candidates[n, 1], candidates[n, 2], candidates[n, 3] = tbe_x[0], tbe_x[1], x0[2], x0[3]
    n += 1
    for c in range(n):
        x = candidates[c]
        finite = np.isfinite(x[0]) and np.isfinite(x[1]) and np.isfinite(x[2]) and np.isfinite(x[3])
        if finite and prm.min_phase_rate <= x[1] <= prm.max_phase_rate and abs(x[3]) <= prm.max_abs_incline:
            _ekf_reset(ekf_x, ekf_P, x, P0)
            break
    else:
        _ekf_reset(ekf_x, ekf_P, x0, P0)
    if prm.use_backup and not (np.all(np.isfinite(bk_x)) and np.all(np.isfinite(bk_P))):
        _new_backup(prm, fs, ns, x0, bk_x, bk_P)


@njit(cache=True)
def _scratch(model: tuple) -> tuple:
    """The work arrays of :func:`step`, and the backup's R factor (``model[3]``) for when all channels are there."""
    rbar, rbar_L = model[2], model[3]
    all_used = np.ones(N_CHANNELS, dtype=np.bool_)
    work = (
        np.zeros((4, 7)),
        np.zeros(4),
        np.zeros(N_CHANNELS),
        np.zeros((N_CHANNELS, 4)),
        np.empty((N_CHANNELS, 2)),
        all_used,
    )
    _kernels.cholesky_used(rbar, all_used, rbar_L)
    q = np.zeros(5)  # EKFConfig.q_diag of the last dt, and that dt (q[4], -1 before any)
    q[4] = -1.0
    return np.empty(N_CHANNELS), np.zeros((4, 7)), work, q


@njit(cache=True, inline="always")
def step(
    tk: float,
    zk: Array,
    given: int,
    prm: _Params,
    model: tuple,
    start: tuple,
    fs: Array,
    ns: NDArray[np.int64],
    ekf: tuple,
    bk: tuple,
    tbe_x: Array,
    hp_zi: Array,
    scratch: tuple,
    command: bool = True,
) -> tuple[bool, bool, int, int, float, float]:
    """``GaitStatePipeline.step(tk, zk, heel_strike, command=command)`` on the state arrays of :func:`run` (see
    :func:`_run`); ``given``: the heel strike, 1 or 0, or -1 to detect it (``heel_strike=None``); without
    ``command`` the torque is 0 and the fault never ``"torque"`` (a stack commands the torque).

    Returns:
        ``(heel strike, backup reset, fault index, implausible count, stride length (m), torque)``; the phase,
        phase rate and incline are ``ekf[0]``'s.
    """
    coef, bins, coef4, lo, hi, unmodelled, hp_b, hp_a, hp_zi_unit = (
        model[0], model[1], model[4], model[5], model[6], model[7], model[8], model[9], model[10]
    )  # fmt: skip
    ekf_x, ekf_P, ekf_y, ekf_S, ekf_K, ekf_zpred, ekf_H, ekf_R = ekf
    z, terms, work, q = scratch
    dt = tk - fs[_F_T] if ns[_I_HAS_T] else 0.0
    fault = _OK
    if dt > prm.max_gap_s:
        _restart(prm, fs, ns, start, ekf, bk, tbe_x)
        ns[_I_RESTARTS] += 1
        fault, dt = _GAP, 0.0
    if not ns[_I_HAS_T] and fs[_F_HEEL_SETTLE] > 0.0:
        fs[_F_HEEL_MASKED_UNTIL], fs[_F_HEEL_SETTLE] = tk + fs[_F_HEEL_SETTLE], 0.0
    fs[_F_T] = tk
    ns[_I_HAS_T] = 1
    z[:] = zk
    implausible = _kernels.screen(z, lo, hi)
    ns[_I_IMPLAUSIBLE] += implausible
    if not prm.heel_filtered:
        ns[_I_HP_STARTED] = _kernels.highpass_step(hp_b, hp_a, hp_zi_unit, hp_zi, ns[_I_HP_STARTED] != 0, z[4:6])
    for i in range(N_CHANNELS):
        if unmodelled[i]:
            z[i] = np.nan
    if tk < fs[_F_HEEL_MASKED_UNTIL]:  # after a restart, until the heel high-pass has settled
        z[4] = z[5] = np.nan
    if given < 0:
        hs = np.isfinite(z[0]) and np.isfinite(z[1]) and _detect(prm, fs, ns, tk, z[0], z[1])
    else:
        hs = given > 0
    if dt > 0:
        if dt != q[4]:  # EKFConfig.q_diag
            c = dt / prm.q_time_unit
            q[0] = 0.0 * c * prm.process_noise_scale
            q[1] = prm.q_var[0] * c * prm.process_noise_scale
            q[2] = prm.q_var[1] * c * prm.process_noise_scale
            q[3] = prm.q_var[2] * c * prm.process_noise_scale
            if prm.no_task:
                q[2] = q[3] = _FROZEN
            q[4] = dt
        _kernels.predict(ekf_x, ekf_P, dt, q)
        fs[_F_TBE_T] += dt
        _tbe_refresh(fs, tbe_x)
    m, maha2, logdet = _kernels.ekf_update(
        coef, ekf_x, ekf_P, z, prm.ekf_leg_length, bins, terms, ekf_zpred, ekf_H, ekf_R, ekf_y, ekf_S, ekf_K
    )
    fs[_F_MAHALANOBIS] = np.sqrt(maha2)
    fs[_F_LOG_LIKELIHOOD] = -0.5 * (maha2 + logdet + m * prm.log_2pi) if m else 0.0
    reset = prm.use_backup and _backup_track(prm, fs, ns, tk, dt, z, hs, model, ekf, bk, work)
    if hs:  # TimingBasedEstimator.update([1])
        if ns[_I_TBE_SEEN_HS]:
            period = fs[_F_TBE_T] - fs[_F_TBE_LAST_HS]
            if fs[_F_TBE_MIN] <= period <= fs[_F_TBE_MAX]:
                fs[_F_TBE_PERIOD] = period
        ns[_I_TBE_SEEN_HS] = 1
        fs[_F_TBE_LAST_HS] = fs[_F_TBE_T]
        _tbe_refresh(fs, tbe_x)
    if not _kernels.healthy(
        ekf_x, ekf_P, prm.min_phase_rate, prm.max_phase_rate, prm.max_abs_incline, prm.max_variance
    ):
        _reset_diverged(prm, fs, ns, start, ekf, bk, tbe_x)
        fault = _DIVERGED
    l_norm = _kernels.stride_from_pseudo(ekf_x[2])[0]
    stride_m = l_norm * prm.leg_length
    torque = 0.0
    if command and fault != _DIVERGED:  # the stack's rule: the stride in metres over the leg length (bit for bit)
        torque = _kernels.bounded_torque(
            coef4, ekf_x[0], stride_m / prm.leg_length, ekf_x[3], prm.cutoff_phase, prm.torque_scale,
            prm.mass_times_gain, prm.max_torque,
        )
        if not 0.0 <= torque <= prm.max_torque:
            torque = 0.0
            if fault == _OK:
                fault = _TORQUE
    return hs, reset, fault, implausible, stride_m, torque


@njit(cache=True, nogil=True)
def _run(
    t: Array,
    Z: Array,
    hs_in: NDArray[np.bool_],
    prm: _Params,
    model: tuple,
    start: tuple,
    fs: Array,
    ns: NDArray[np.int64],
    ekf: tuple,
    bk: tuple,
    tbe_x: Array,
    hp_zi: Array,
    out: Array,
    out_flags: NDArray[np.int64],
) -> None:
    """``GaitStatePipeline.step`` for every row of ``Z`` (:func:`step`).

    ``model``: gait-model coefficients, ``Sigma_R`` bins, the backup's R and its Cholesky factor (filled
    here), torque coefficients, channel bounds low and high, unmodelled channels, high-pass b, a and
    unit state. ``start``: the EKF's initial state and covariance. ``ekf``: x, P, y, S, K, z_pred, H, R.
    ``bk``: the backup's x, P, y, S, K. ``out`` columns: phase, phase rate, stride length (m), incline,
    torque, TBE phase; ``out_flags``: heel strike, backup reset, fault index, implausible count.
    """
    ekf_x = ekf[0]
    scratch = _scratch(model)
    for k in range(t.shape[0]):
        given = -1 if prm.detect else (1 if hs_in[k] else 0)
        hs, reset, fault, implausible, stride_m, torque = step(
            t[k], Z[k], given, prm, model, start, fs, ns, ekf, bk, tbe_x, hp_zi, scratch
        )
        out[k, 0] = ekf_x[0]
        out[k, 1] = ekf_x[1]
        out[k, 2] = stride_m
        out[k, 3] = ekf_x[3]
        out[k, 4] = torque
        out[k, 5] = tbe_x[0]
        out_flags[k, 0] = hs
        out_flags[k, 1] = reset
        out_flags[k, 2] = fault
        out_flags[k, 3] = implausible


def _c(a: Array) -> Array:
    """A C-contiguous float64 array (the same array if it is one): one compiled signature for all."""
    return np.ascontiguousarray(a, dtype=np.float64)


def _check(pipe: GaitStatePipeline, t: Array, z: Array, heel_strike: NDArray[np.bool_] | None) -> None:
    """The input errors :meth:`GaitStatePipeline.step` would raise at some sample, raised up front."""
    n = t.shape[0]
    if z.shape != (n, N_CHANNELS):
        raise ValueError(f"z must have shape ({n}, {N_CHANNELS}) for {n} times, got {z.shape}")
    if heel_strike is not None and np.shape(heel_strike) != (n,):
        raise ValueError(f"heel_strike must have shape ({n},), got {np.shape(heel_strike)}")
    bad = ~np.isfinite(t)
    if bad.any():
        raise ValueError(f"time must be finite, got {t[int(np.argmax(bad))]}")
    prev = t[:-1] if pipe._t is None else np.concatenate(([pipe._t], t[:-1]))
    later = t[1:] if pipe._t is None else t
    back = ~(later - prev > 0)
    if back.any():
        i = int(np.argmax(back))
        raise ValueError(f"time must increase: {float(later[i])} after {float(prev[i])}")


class State(NamedTuple):
    """A pipeline's constants and whole state as :func:`step` takes them (see :func:`_run`)."""

    prm: _Params
    model: tuple
    start: tuple
    fs: Array
    ns: NDArray[np.int64]
    ekf: tuple
    bk: tuple
    tbe_x: Array
    hp_zi: Array


def state(pipe: GaitStatePipeline, detect: bool, heel_filtered: bool) -> State:
    """``pipe``'s state in arrays (the EKF's own arrays themselves, updated in place by :func:`step`); ``detect``:
    heel strikes are detected (:func:`_run`; :func:`step` takes them per sample)."""
    cfg = pipe.config
    ekf, bk, tbe, det, hp = pipe.ekf, pipe.backup, pipe.tbe, pipe.detector, pipe.highpass
    bcfg, dcfg, lim, torque = cfg.backup, cfg.detector, cfg.health, pipe.model.torque
    fresh_tbe = type(tbe)()  # what a restart makes
    q_var = tuple(float(s * s) for s in ekf.config.q_std)
    prm = _Params(
        max_gap_s=float(cfg.max_gap_s),
        q_var=(q_var[0], q_var[1], q_var[2]),
        q_time_unit=float(ekf.config.q_time_unit),
        process_noise_scale=float(ekf.config.process_noise_scale),
        no_task=bool(ekf.config.no_task),
        ekf_leg_length=ekf.leg_length,
        log_2pi=math.log(2.0 * math.pi),
        use_backup=bk is not None,
        backup_q_rate=(float(bcfg.q_rate[0]), float(bcfg.q_rate[1])),
        sse_margin=float(bcfg.sse_margin),
        reset_p=float(bcfg.reset_p),
        backup_min_period=float(bcfg.min_period),
        backup_max_period=float(bcfg.max_period),
        backup_initial_period=float(bcfg.initial_period),
        backup_p0=float(bcfg.p0),
        detect=bool(detect),
        max_foot_angle_deg=float(dcfg.max_foot_angle_deg),
        refractory_s=float(dcfg.refractory_s),
        accel_threshold_set=dcfg.accel_threshold is not None,
        heel_filtered=bool(heel_filtered),
        min_phase_rate=float(lim.min_phase_rate),
        max_phase_rate=float(lim.max_phase_rate),
        max_abs_incline=float(lim.max_abs_incline),
        max_variance=float(lim.max_variance),
        torque_scale=float(torque.scale),
        cutoff_phase=float(torque.cutoff_phase),
        mass_times_gain=float(cfg.body_mass_kg * cfg.torque_gain),
        max_torque=float(cfg.max_torque),
        leg_length=float(cfg.leg_length),
        tbe_initial_period=float(fresh_tbe.period),
        tbe_min_period=float(fresh_tbe.min_period),
        tbe_max_period=float(fresh_tbe.max_period),
    )

    fs = np.zeros(17)
    fs[_F_HEEL_SETTLE], fs[_F_HEEL_MASKED_UNTIL] = pipe._heel_settle, pipe._heel_masked_until
    ns = np.zeros(9, dtype=np.int64)
    if pipe._t is not None:
        fs[_F_T], ns[_I_HAS_T] = pipe._t, 1
    ns[_I_IMPLAUSIBLE], ns[_I_RESTARTS], ns[_I_RESETS] = pipe.implausible, pipe.restarts, pipe.resets
    fs[_F_LOG_LIKELIHOOD], fs[_F_MAHALANOBIS] = ekf.log_likelihood, ekf.mahalanobis
    if bk is not None:
        fs[_F_BK_PHASE], fs[_F_BK_RATE] = bk.phase, bk.phase_rate
        fs[_F_BK_SSE_EKF], fs[_F_BK_SSE_HP], ns[_I_BK_RESETS] = bk.sse_ekf, bk.sse_hp, bk.resets
        if bk._last_hs is not None:
            fs[_F_BK_LAST_HS], ns[_I_BK_HAS_LAST_HS] = bk._last_hs, 1
        bk_arrays = (bk.x, bk.P, bk._y, bk._S, bk._K)
        rbar = bk._rbar
    else:
        bk_arrays = (np.zeros(2), np.zeros((2, 2)), np.zeros(N_CHANNELS), np.zeros((6, 6)), np.zeros((2, 6)))
        rbar = np.eye(N_CHANNELS)
    fs[_F_TBE_PERIOD], fs[_F_TBE_T], fs[_F_TBE_LAST_HS] = tbe.period, tbe.t, tbe._last_hs
    fs[_F_TBE_MIN], fs[_F_TBE_MAX], ns[_I_TBE_SEEN_HS] = tbe.min_period, tbe.max_period, tbe._seen_hs
    fs[_F_DET_LAST_HS], fs[_F_DET_PREV_VEL] = det._last_hs, det._prev_vel
    ns[_I_ACCEL_BLOCKED] = prm.accel_threshold_set and (
        not det._acc or float(np.mean(det._acc)) < float(dcfg.accel_threshold or 0.0)
    )
    hp_zi = np.zeros((2, 2))
    if hp._zi is not None:
        hp_zi[:], ns[_I_HP_STARTED] = hp._zi, 1

    # the filters' own arrays (they are C-contiguous float64: _c returns them, not copies)
    ekf_arrays = tuple(_c(a) for a in (ekf.x, ekf.P, ekf.y, ekf.S, ekf.K, ekf.z_pred, ekf.H, ekf.R))
    bk_work = tuple(_c(a) for a in bk_arrays)
    tbe_x = _c(tbe.x)
    coef4, _ = torque._workspace
    model = (
        _c(ekf.coef), _c(ekf._bins), _c(rbar), np.zeros((N_CHANNELS, N_CHANNELS)), _c(coef4), _c(pipe._lo),
        _c(pipe._hi), np.ascontiguousarray(pipe._unmodelled, dtype=np.bool_), _c(hp.b), _c(hp.a), _c(hp._zi_unit),
    )  # fmt: skip
    start = (_c(cfg.ekf.initial_state()), _c(cfg.ekf.initial_covariance()))
    return State(prm, model, start, fs, ns, ekf_arrays, bk_work, tbe_x, hp_zi)


def store(pipe: GaitStatePipeline, st: State) -> None:
    """Write ``st`` back into ``pipe``'s objects (:func:`state`'s inverse)."""
    fs, ns, ekf_arrays, bk_work, tbe_x, hp_zi = st.fs, st.ns, st.ekf, st.bk, st.tbe_x, st.hp_zi
    ekf, bk, tbe, det, hp = pipe.ekf, pipe.backup, pipe.tbe, pipe.detector, pipe.highpass
    if ns[_I_HAS_T]:
        pipe._t = float(fs[_F_T])
    pipe._heel_settle, pipe._heel_masked_until = float(fs[_F_HEEL_SETTLE]), float(fs[_F_HEEL_MASKED_UNTIL])
    restarted = int(ns[_I_RESTARTS]) != pipe.restarts
    pipe.implausible, pipe.restarts, pipe.resets = int(ns[_I_IMPLAUSIBLE]), int(ns[_I_RESTARTS]), int(ns[_I_RESETS])
    for mine, theirs in zip(ekf_arrays, (ekf.x, ekf.P, ekf.y, ekf.S, ekf.K, ekf.z_pred, ekf.H, ekf.R), strict=True):
        theirs[...] = mine
    ekf.log_likelihood, ekf.mahalanobis = float(fs[_F_LOG_LIKELIHOOD]), float(fs[_F_MAHALANOBIS])
    if bk is not None:
        bk_arrays = (bk.x, bk.P, bk._y, bk._S, bk._K)
        for mine, theirs in zip(bk_work, bk_arrays, strict=True):
            theirs[...] = mine
        bk.phase, bk.phase_rate = float(fs[_F_BK_PHASE]), float(fs[_F_BK_RATE])
        bk.sse_ekf, bk.sse_hp, bk.resets = float(fs[_F_BK_SSE_EKF]), float(fs[_F_BK_SSE_HP]), int(ns[_I_BK_RESETS])
        bk._last_hs = float(fs[_F_BK_LAST_HS]) if ns[_I_BK_HAS_LAST_HS] else None
    tbe.period, tbe.t, tbe._last_hs = float(fs[_F_TBE_PERIOD]), float(fs[_F_TBE_T]), float(fs[_F_TBE_LAST_HS])
    tbe.min_period, tbe.max_period = float(fs[_F_TBE_MIN]), float(fs[_F_TBE_MAX])
    tbe._seen_hs = bool(ns[_I_TBE_SEEN_HS])
    tbe.x[:] = tbe_x
    if restarted:  # a new TBE and a new detector: its acceleration history is gone
        tbe.initial_period = type(tbe)().initial_period
        det._heel.clear()
        det._acc.clear()
    det._last_hs, det._prev_vel = float(fs[_F_DET_LAST_HS]), float(fs[_F_DET_PREV_VEL])
    hp._zi = hp_zi.copy() if ns[_I_HP_STARTED] else None


def run(
    pipe: GaitStatePipeline,
    t: Array,
    z: Array,
    heel_strike: NDArray[np.bool_] | None = None,
    heel_filtered: bool = False,
) -> dict[str, NDArray[np.generic]]:
    """Run ``pipe`` over ``len(t)`` samples; see :meth:`GaitStatePipeline.run`."""
    t = _c(t).reshape(-1)
    z = _c(z)
    _check(pipe, t, z, heel_strike)
    n = t.shape[0]
    hs_in = np.zeros(n, dtype=np.bool_) if heel_strike is None else np.ascontiguousarray(heel_strike, dtype=np.bool_)
    st = state(pipe, heel_strike is None, heel_filtered)
    out = np.empty((n, 6))
    flags = np.empty((n, 4), dtype=np.int64)
    _run(t, z, hs_in, *st, out, flags)
    store(pipe, st)
    return {
        "phase": out[:, 0],
        "phase_rate": out[:, 1],
        "stride_length_m": out[:, 2],
        "incline_deg": out[:, 3],
        "torque_Nm": out[:, 4],
        "heel_strike": flags[:, 0].astype(np.bool_),
        "tbe_phase": out[:, 5],
        "backup_reset": flags[:, 1].astype(np.bool_),
        "fault": np.array(FAULTS)[flags[:, 2]],
        "implausible": flags[:, 3],
    }
