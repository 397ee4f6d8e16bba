"""The supervised replay's stack in one compiled loop: what stepping a stack of ``phase_ekf`` (the pipeline under
its lock supervisor) and ``tbe`` does, sample after sample, bit for bit. Private: the replay uses it
(:mod:`gaitscope.sessions.offline.replay`), ``tests/estimators/test_lock_batch.py`` checks it against stepping.

Per sample, as :meth:`PhaseEKFEstimator.step <gaitscope.estimators.phase_ekf_estimator.PhaseEKFEstimator.step>`
and the stack (:class:`~gaitscope.sessions.stack.EstimatorStack`) do it, with the same floating-point operations
in the same order:

1. the supervisor's motion (:meth:`LockSupervisor.motion <gaitscope.estimators.lock.LockSupervisor.motion>`:
   standing detected, left, the standing weight); standing, the outputs are the held ones and the pipeline waits;
2. walking: the shank's heel strike (:class:`~gaitscope.estimators.lock.ShankHeelStrike`), used when the input
   gives none and there is no foot angle; on resuming, the pipeline's restart at the posture's phase
   advanced by the cadence since the motion's onset; the pipeline's step (:func:`gaitscope.estimators._batch.step`,
   heel positions left out while their high-pass settles); lock loss
   (:meth:`LockSupervisor.lost <gaitscope.estimators.lock.LockSupervisor.lost>`) and the reset from the backup;
   the state of the last heel strike walked;
3. the stack: the estimator's health as the stack checks it, the heel-strike channel (the input's, else the
   estimator's), the timing-based estimate ``tbe`` on it, and the torque rule (the profile at the estimator's
   phase, stride over the leg length and incline, times one less the standing weight; 0 at a reset; finite and
   within the bound).

What it does not do: the stack's isolation. A sample on which the stack would mark an estimator failed (a
non-finite output, a covariance the stack refuses) stops the loop and :meth:`LockBatch.run` returns its index;
the caller replays the trial by stepping (which reports the failure as the stack does). Nor the stack's other
estimators, a switch of the primary, or a retune: the replay has none of them.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray

from gaitscope.estimators import _batch, _kernels
from gaitscope.estimators.basis import Array
from gaitscope.estimators.phase_ekf_estimator import PhaseEKFEstimator
from gaitscope.estimators.tbe import TimingBasedEstimator
from gaitscope.estimators.torque import TorqueProfile

__all__ = ["LockBatch"]

# the supervisor's, the stack's TBE's and the replay's float state
(
    _S_STILL_SINCE, _S_STILL_PHASE, _S_CHANGED_T, _S_LAST_HS, _S_OUT_SINCE, _S_ONSET, _S_HELD_PHASE, _S_WEIGHT,
    _S_TBE_PERIOD, _S_TBE_T, _S_TBE_LAST_HS, _S_TBE_PREV_T, _S_TBE_PHASE, _S_TBE_RATE, _S_PREV_T, _S_STANDING_S,
    _S_HS1, _S_HS2,
) = range(18)  # fmt: skip
# integer state: flags (a None in the Python objects is a flag of 0) and counts
(
    _N_STANDING, _N_ARMED, _N_HAS_STILL_SINCE, _N_HAS_LAST_HS, _N_HAS_OUT_SINCE, _N_HAS_ONSET, _N_HAS_WALKING,
    _N_TBE_SEEN_HS, _N_TBE_HAS_T, _N_HAS_PREV_T, _N_LOST, _N_BACKUP_RESETS, _N_HS_SEEN, _N_ADAPT_LEFT,
) = range(14)  # fmt: skip
_NONE, _STANDING, _RESUMED = 0, 1, 2  # LockSupervisor.motion's events
# phase_ekf's fault codes (gaitscope.estimators.protocol.FAULTS) for the pipeline's faults (_batch.FAULTS)
_CODE_OF_FAULT = (0.0, 1.0, 2.0, 0.0)
_DIVERGED_CODE, _LOST_CODE, _RESUMED_CODE = 2.0, 4.0, 5.0


class _LockParams(NamedTuple):
    """The supervisor's thresholds (:class:`~gaitscope.estimators.lock.LockConfig`), the stack's torque rule
    and health limit, and the stack's TBE's periods."""

    enabled: bool
    still_dps: float
    still_s: float
    move_dps: float
    ramp_s: float
    resume_phase: float
    heel_settle_s: float
    shank_swing_dps: float
    max_stride_s: float
    rate_lo: float
    rate_hi: float
    out_of_range_s: float
    backdate_resume: bool
    onset_dps: float
    advance_at_onset: bool
    cadence_change: float
    adapt_strides: int
    adapt_after_resume: int
    rate_q: float  # PhaseEKFEstimator._rate_q
    leg_length: float  # the stack's
    torque_scale: float
    cutoff_phase: float
    mass_times_gain: float
    max_torque: float
    max_variance: float
    tbe_initial_period: float
    tbe_min_period: float
    tbe_max_period: float
    tbe_max_gap_s: float


@njit(cache=True)
def _motion(lp: _LockParams, sfs: Array, sns: NDArray[np.int64], t: float, foot_dps: float, shank_dps: float,
            phase: float) -> int:  # fmt: skip
    """``LockSupervisor.motion``; returns its event."""
    if not lp.enabled:
        return _NONE
    have, fastest = False, 0.0
    for v in (foot_dps, shank_dps):
        if v == v:
            a = abs(v)
            if not have or a > fastest:  # max(rates): the first of equals
                fastest = a
            have = True
    event = _NONE
    if have:
        if sns[_N_STANDING]:
            if fastest < lp.onset_dps or not sns[_N_HAS_ONSET]:
                if fastest < lp.onset_dps:
                    sns[_N_HAS_ONSET] = 0
                else:
                    sfs[_S_ONSET], sns[_N_HAS_ONSET] = t, 1
            if fastest > lp.move_dps:
                sns[_N_STANDING], sfs[_S_CHANGED_T], event = 0, t, _RESUMED
                sns[_N_HAS_STILL_SINCE] = 0
                sfs[_S_LAST_HS], sns[_N_HAS_LAST_HS] = t, 1
                sns[_N_HS_SEEN], sns[_N_ADAPT_LEFT] = 0, lp.adapt_after_resume
        elif fastest < lp.still_dps:
            if not sns[_N_HAS_STILL_SINCE]:
                sfs[_S_STILL_SINCE], sfs[_S_STILL_PHASE], sns[_N_HAS_STILL_SINCE] = t, phase, 1
            elif t - sfs[_S_STILL_SINCE] >= lp.still_s:
                sns[_N_STANDING], sfs[_S_CHANGED_T], event = 1, t, _STANDING
                sfs[_S_HELD_PHASE] = sfs[_S_STILL_PHASE]
        else:
            sns[_N_HAS_STILL_SINCE] = 0
    ramp = 1.0
    if lp.ramp_s > 0:
        r = (t - sfs[_S_CHANGED_T]) / lp.ramp_s
        if r < 1.0:  # min(1.0, r)
            ramp = r
    sfs[_S_WEIGHT] = ramp if sns[_N_STANDING] else 1.0 - ramp
    if sns[_N_STANDING] and ramp >= 1.0:
        sfs[_S_HELD_PHASE] = lp.resume_phase
    return event


@njit(cache=True)
def _resume_state(lp: _LockParams, sfs: Array, sns: NDArray[np.int64], walking: Array, start: tuple, t: float,
                  x0: Array) -> None:  # fmt: skip
    """``PhaseEKFEstimator._resume_state`` into ``x0``."""
    x0[:] = walking if sns[_N_HAS_WALKING] else start[0]
    x0[0] = lp.resume_phase
    if lp.backdate_resume and sns[_N_HAS_ONSET]:
        since = t - sfs[_S_ONSET]
        x0[0] += (lp.still_s if lp.still_s < since else since) * x0[1]  # min(since, still_s)


@njit(cache=True)
def _adapting(lp: _LockParams, sfs: Array, sns: NDArray[np.int64], t: float, heel_strike: bool) -> bool:
    """``LockSupervisor.adapting``."""
    if not lp.enabled or sns[_N_STANDING]:
        return False
    if heel_strike:
        if sns[_N_ADAPT_LEFT] > 0:
            sns[_N_ADAPT_LEFT] -= 1
        if sns[_N_HS_SEEN] >= 2 and abs((t - sfs[_S_HS1]) / (sfs[_S_HS1] - sfs[_S_HS2]) - 1.0) > lp.cadence_change:
            if sns[_N_ADAPT_LEFT] < lp.adapt_strides:  # max(adapt_left, adapt_strides)
                sns[_N_ADAPT_LEFT] = lp.adapt_strides
        sfs[_S_HS2], sfs[_S_HS1] = sfs[_S_HS1], t
        if sns[_N_HS_SEEN] < 2:
            sns[_N_HS_SEEN] += 1
    return sns[_N_ADAPT_LEFT] > 0


@njit(cache=True)
def _lost(lp: _LockParams, sfs: Array, sns: NDArray[np.int64], t: float, heel_strike: bool, rate: float) -> bool:
    """``LockSupervisor.lost``: whether the filter lost track at this sample."""
    if not lp.enabled:
        return False
    if heel_strike or not sns[_N_HAS_LAST_HS]:
        sfs[_S_LAST_HS], sns[_N_HAS_LAST_HS] = t, 1
    if sns[_N_STANDING]:
        sns[_N_HAS_OUT_SINCE] = 0
        return False
    if t - sfs[_S_LAST_HS] > lp.max_stride_s:
        sfs[_S_LAST_HS] = t
        return True
    if lp.rate_lo <= rate <= lp.rate_hi:
        sns[_N_HAS_OUT_SINCE] = 0
    elif not sns[_N_HAS_OUT_SINCE]:
        sfs[_S_OUT_SINCE], sns[_N_HAS_OUT_SINCE] = t, 1
    elif t - sfs[_S_OUT_SINCE] > lp.out_of_range_s:
        sns[_N_HAS_OUT_SINCE] = 0
        return True
    return False


@njit(cache=True)
def _tbe_start(lp: _LockParams, sfs: Array, sns: NDArray[np.int64]) -> None:
    """``TimingBasedEstimator._start``."""
    sfs[_S_TBE_PERIOD], sfs[_S_TBE_T], sfs[_S_TBE_LAST_HS] = lp.tbe_initial_period, 0.0, 0.0
    sns[_N_TBE_SEEN_HS] = 0
    sfs[_S_TBE_PHASE], sfs[_S_TBE_RATE] = 0.0, 1.0 / lp.tbe_initial_period


@njit(cache=True)
def _tbe_refresh(sfs: Array) -> None:
    sfs[_S_TBE_PHASE] = ((sfs[_S_TBE_T] - sfs[_S_TBE_LAST_HS]) / sfs[_S_TBE_PERIOD]) % 1.0
    sfs[_S_TBE_RATE] = 1.0 / sfs[_S_TBE_PERIOD]


@njit(cache=True)
def _tbe_step(lp: _LockParams, sfs: Array, sns: NDArray[np.int64], t: float, heel_strike: float) -> None:
    """``TimingBasedEstimator.step(t, [heel_strike])`` (the times increase: checked before the loop)."""
    dt = 0.0
    if sns[_N_TBE_HAS_T]:
        dt = t - sfs[_S_TBE_PREV_T]
        if dt > lp.tbe_max_gap_s:
            _tbe_start(lp, sfs, sns)
            dt = 0.0
    sfs[_S_TBE_PREV_T], sns[_N_TBE_HAS_T] = t, 1
    if dt > 0:
        sfs[_S_TBE_T] += dt
        _tbe_refresh(sfs)
    if heel_strike > 0.5:
        if sns[_N_TBE_SEEN_HS]:
            period = sfs[_S_TBE_T] - sfs[_S_TBE_LAST_HS]
            if lp.tbe_min_period <= period <= lp.tbe_max_period:
                sfs[_S_TBE_PERIOD] = period
        sns[_N_TBE_SEEN_HS] = 1
        sfs[_S_TBE_LAST_HS] = sfs[_S_TBE_T]
        _tbe_refresh(sfs)


@njit(cache=True)
def _finite(v: float) -> float:
    return v if np.isfinite(v) else 0.0


@njit(cache=True)
def _refused(lp: _LockParams, y: Array, P: Array) -> bool:
    """The stack would mark the estimator failed (``EstimatorStack._unhealthy``): a sum of its outputs or of
    its covariance that is not finite (as the stack sums them, left to right), a variance out of range."""
    acc = 0.0
    for v in y:
        acc += v
    if not np.isfinite(acc):
        return True
    acc = 0.0
    for i in range(P.shape[0]):
        for j in range(P.shape[1]):
            acc += P[i, j]
    if not np.isfinite(acc):
        return True
    lo, hi = P[0, 0], P[0, 0]
    for i in range(1, P.shape[0]):
        lo = P[i, i] if P[i, i] < lo else lo
        hi = P[i, i] if P[i, i] > hi else hi
    return lo < 0 or hi > lp.max_variance


@njit(cache=True, nogil=True)
def _run(
    t: Array,
    Z: Array,
    H: Array,
    lp: _LockParams,
    coef4: Array,
    sfs: Array,
    sns: NDArray[np.int64],
    walking: Array,
    prm: _batch._Params,
    model: tuple,
    start: tuple,
    fs: Array,
    ns: NDArray[np.int64],
    ekf: tuple,
    bk: tuple,
    tbe_x: Array,
    hp_zi: Array,
    out: Array,
    out_hs: NDArray[np.bool_],
) -> int:
    """The stack for every row of ``Z`` (raw measurements) and ``H`` (the input's heel strike, NaN: none);
    see :class:`LockBatch`. ``out`` columns: phase, phase rate, stride length (m), incline, torque, TBE phase.

    Returns:
        -1, or the index of the sample on which the stack would mark ``phase_ekf`` or ``tbe`` failed (the
        outputs and the state from it on are not the stack's).
    """
    ekf_x, ekf_P, ekf_zpred = ekf[0], ekf[1], ekf[5]
    scratch = _batch._scratch(model)
    y = np.empty(10)  # phase_ekf's outputs
    x0 = np.empty(4)
    for k in range(t.shape[0]):
        tk = t[k]
        zk = Z[k]
        given_hs = H[k]
        foot, foot_dps, shank_dps = zk[0], zk[1], zk[3]
        event = _motion(lp, sfs, sns, tk, foot_dps, shank_dps, ekf_x[0])
        if sns[_N_STANDING]:  # phase held, rate 0, the filters wait
            y[0], y[1] = sfs[_S_HELD_PHASE], 0.0
            if lp.advance_at_onset and sns[_N_HAS_ONSET]:  # moving: as the restart would start
                _resume_state(lp, sfs, sns, walking, start, tk, x0)
                y[0], y[1] = x0[0] % 1.0, x0[1]
            y[2] = _finite(_kernels.stride_from_pseudo(ekf_x[2])[0] * prm.leg_length)
            y[3] = _finite(ekf_x[3])
            y[4] = y[5] = y[6] = 0.0
        else:
            shank_hs = False  # ShankHeelStrike.step
            if shank_dps > lp.shank_swing_dps:
                sns[_N_ARMED] = 1
            elif sns[_N_ARMED] and shank_dps < 0.0:
                sns[_N_ARMED] = 0
                shank_hs = True
            given = -1 if given_hs != given_hs else (1 if given_hs > 0.5 else 0)
            if given < 0 and foot != foot and shank_dps == shank_dps and lp.enabled:
                given = 1 if shank_hs else 0  # no foot sensor to detect heel strikes from: the shank's
            if event == _RESUMED:  # GaitStatePipeline.restart at the cadence, stride and slope walked before
                _resume_state(lp, sfs, sns, walking, start, tk, x0)
                _batch._restart(prm, fs, ns, start, ekf, bk, tbe_x)
                ns[_batch._I_RESTARTS] += 1
                ns[_batch._I_HAS_T] = 0
                fs[_batch._F_HEEL_SETTLE] = lp.heel_settle_s
                _batch._ekf_reset(ekf_x, ekf_P, x0, start[1])
            hs, reset, fault, _, stride_m, _ = _batch.step(
                tk, zk, given, prm, model, start, fs, ns, ekf, bk, tbe_x, hp_zi, scratch, False
            )
            code = _RESUMED_CODE if event == _RESUMED else _CODE_OF_FAULT[fault]
            y[2], y[3] = stride_m, ekf_x[3]
            if _lost(lp, sfs, sns, tk, hs, ekf_x[1]) and fault == 0:
                _batch._reset_diverged(prm, fs, ns, start, ekf, bk, tbe_x)  # reset_from_backup
                code = _LOST_CODE
            if _adapting(lp, sfs, sns, tk, hs):  # the cadence changes: the phase rate follows it faster
                ekf_P[1, 1] += lp.rate_q * ((tk - sfs[_S_PREV_T]) if sns[_N_HAS_PREV_T] else 0.0)
            y[0], y[1] = ekf_x[0], ekf_x[1]
            if hs and lp.rate_lo <= y[1] <= lp.rate_hi:  # the state at the last heel strike walking
                walking[:] = ekf_x
                sns[_N_HAS_WALKING] = 1
            y[4], y[5], y[6] = 1.0 if hs else 0.0, 1.0 if reset else 0.0, code
        y[7], y[8], y[9] = _finite(ekf_zpred[0]), _finite(ekf_zpred[2]), sfs[_S_WEIGHT]
        if _refused(lp, y, ekf_P):
            return k
        hs_channel = given_hs if given_hs == given_hs else y[4]  # the input's, else phase_ekf's
        _tbe_step(lp, sfs, sns, tk, hs_channel)
        if not np.isfinite(0.0 + sfs[_S_TBE_PHASE] + sfs[_S_TBE_RATE]):
            return k
        torque = 0.0  # EstimatorStack._command, then its bound
        if not (y[6] == _DIVERGED_CODE or y[6] == _LOST_CODE):
            still = y[9] if 0.0 <= y[9] <= 1.0 else 0.0
            torque = _kernels.bounded_torque(
                coef4,
                y[0],
                y[2] / lp.leg_length,
                y[3],
                lp.cutoff_phase,
                lp.torque_scale,
                lp.mass_times_gain,
                lp.max_torque,
            ) * (1.0 - still)
        if not np.isfinite(torque):
            torque = 0.0
        if 0.0 > torque:
            torque = 0.0
        if lp.max_torque < torque:
            torque = lp.max_torque
        out[k, 0], out[k, 1], out[k, 2], out[k, 3], out[k, 4] = y[0], y[1], y[2], y[3], torque
        out[k, 5] = sfs[_S_TBE_PHASE]
        out_hs[k] = hs_channel > 0.5
        sns[_N_BACKUP_RESETS] += y[5] > 0.5
        sns[_N_LOST] += y[6] == _LOST_CODE
        if y[9] >= 1.0 and sns[_N_HAS_PREV_T]:
            sfs[_S_STANDING_S] += tk - sfs[_S_PREV_T]
        sfs[_S_PREV_T], sns[_N_HAS_PREV_T] = tk, 1
    return -1


class LockBatch:
    """A fresh stack of ``phase_ekf`` (``ekf``, under its supervisor) and ``tbe`` run in compiled parts.

    Takes the estimators' configuration and their (fresh) state when made; from then on the state lives
    here, not in the objects, which are left as they were.

    Args:
        ekf, tbe: the stack's estimators, not yet stepped.
        torque: the stack's torque profile; leg_length, mass_kg, torque_gain, max_torque: its torque rule.
        max_variance: the largest variance the stack accepts in a covariance.

    Attributes:
        backup_resets, lost: samples on which the backup reset the filter, on which it lost track.
        standing_s: time standing, at full weight (s; from each such sample's predecessor).
    """

    def __init__(
        self,
        ekf: PhaseEKFEstimator,
        tbe: TimingBasedEstimator,
        torque: TorqueProfile,
        leg_length: float,
        mass_kg: float,
        torque_gain: float,
        max_torque: float,
        max_variance: float,
    ):
        if ekf.pipeline._t is not None or tbe._t is not None:
            raise ValueError("LockBatch takes estimators that have not been stepped")
        c = ekf.supervisor.config
        self._lp = _LockParams(
            enabled=bool(c.enabled),
            still_dps=float(c.still_dps),
            still_s=float(c.still_s),
            move_dps=float(c.move_dps),
            ramp_s=float(c.ramp_s),
            resume_phase=float(c.resume_phase),
            heel_settle_s=float(c.heel_settle_s),
            shank_swing_dps=float(ekf.supervisor.shank.swing_dps),
            max_stride_s=float(c.max_stride_s),
            rate_lo=float(c.phase_rate_range[0]),
            rate_hi=float(c.phase_rate_range[1]),
            out_of_range_s=float(c.out_of_range_s),
            backdate_resume=bool(c.backdate_resume),
            onset_dps=float(c.onset_dps),
            advance_at_onset=bool(c.advance_at_onset),
            cadence_change=float(c.cadence_change),
            adapt_strides=int(c.adapt_strides),
            adapt_after_resume=int(c.adapt_after_resume),
            rate_q=float(ekf._rate_q),
            leg_length=float(leg_length),
            torque_scale=float(torque.scale),
            cutoff_phase=float(torque.cutoff_phase),
            mass_times_gain=float(mass_kg * torque_gain),
            max_torque=float(max_torque),
            max_variance=float(max_variance),
            tbe_initial_period=float(tbe.initial_period),
            tbe_min_period=float(tbe.min_period),
            tbe_max_period=float(tbe.max_period),
            tbe_max_gap_s=float(tbe.max_gap_s),
        )
        self._coef4 = np.ascontiguousarray(torque._workspace[0], dtype=np.float64)
        self._sfs = np.zeros(18)
        self._sns = np.zeros(14, dtype=np.int64)
        self._sfs[_S_CHANGED_T] = -math.inf
        self._sfs[_S_TBE_PERIOD], self._sfs[_S_TBE_T], self._sfs[_S_TBE_LAST_HS] = tbe.period, tbe.t, tbe._last_hs
        self._sfs[_S_TBE_PHASE], self._sfs[_S_TBE_RATE] = tbe.x[0], tbe.x[1]
        self._walking = np.zeros(4)
        # the pipeline's state arrays: a copy, so that the estimator's own filters are left as they were
        pipe = ekf.pipeline
        st = _batch.state(pipe, detect=True, heel_filtered=False)
        self._pipe = st._replace(ekf=tuple(a.copy() for a in st.ekf), bk=tuple(a.copy() for a in st.bk),
                                 tbe_x=st.tbe_x.copy())  # fmt: skip
        self._t: float | None = None

    @property
    def backup_resets(self) -> int:
        return int(self._sns[_N_BACKUP_RESETS])

    @property
    def lost(self) -> int:
        return int(self._sns[_N_LOST])

    @property
    def standing_s(self) -> float:
        return float(self._sfs[_S_STANDING_S])

    def run(self, t: Array, z: Array, heel_strike: Array, out: Array, out_hs: NDArray[np.bool_]) -> int:
        """The next ``len(t)`` samples.

        Args:
            t: ``(n,)`` times (s), finite and increasing (after the last part's too).
            z: ``(n, 6)`` the six sensor channels (raw heel positions), NaN where missing.
            heel_strike: ``(n,)`` the input's heel strike (1.0 / 0.0), NaN where it has none.
            out: ``(n, 6)`` receives phase, phase rate, stride length (m), incline, torque and TBE phase.
            out_hs: ``(n,)`` receives the heel-strike channel.

        Returns:
            -1, or the index in this part of the first sample on which the stack would mark an estimator
            failed: the outputs from it on are not the stack's, and the state is spoilt.

        Raises:
            ValueError: a time not finite or not after the one before (the stack raises at that sample).
        """
        t = np.ascontiguousarray(t, dtype=np.float64)
        if t.size:
            prev = t[:-1] if self._t is None else np.concatenate(([self._t], t[:-1]))
            later = t[1:] if self._t is None else t
            if not (np.all(np.isfinite(t)) and np.all(later - prev > 0)):
                raise ValueError("the times must be finite and increasing")
            self._t = float(t[-1])
        p = self._pipe
        return int(
            _run(t, np.ascontiguousarray(z, dtype=np.float64), np.ascontiguousarray(heel_strike, dtype=np.float64),
                 self._lp, self._coef4, self._sfs, self._sns, self._walking, p.prm, p.model, p.start, p.fs, p.ns,
                 p.ekf, p.bk, p.tbe_x, p.hp_zi, out, out_hs)
        )  # fmt: skip
