"""Replay a recorded trial (the replay CSV) through the estimator stack.

Reads the input with full validation (:mod:`gaitscope.sessions.formats.replay_io`), derives missing angular
velocities from the angles as a live session does (:func:`~gaitscope.sessions.estimation.backward_difference`),
and runs the trial through a session's estimator stack
(:func:`replay_stack`: :class:`~gaitscope.sessions.stack.EstimatorStack` with the phase EKF ``phase_ekf`` driving
the torque and the timing-based estimate ``tbe``, as :func:`gaitscope.sessions.registry.build_stack` makes them
for a live session), sample by sample as a device streams it: the estimates, the torque and its rule are the
stack's, the one sensor-to-torque path of live sessions, re-runs and imports. The output is written atomically.

``supervised=True`` (what ``gaitscope replay`` and ``gaitscope demo`` do unless ``--as-published``) runs the phase
EKF as a live session's ``phase_ekf`` does, with its lock supervisor (:mod:`gaitscope.estimators.lock`: standing
still, heel strikes from the shank, lock loss; the stack takes the torque to 0 standing and at a lock-loss reset).
``supervised=False`` is seed 000's filter as published (the supervisor off). Both have a compiled fast path,
``batch=True`` (the default), one compiled call per part whose outputs equal stepping the stack bit for bit
(``tests/sessions/offline/test_replay.py``): supervised, the stack's loop compiled whole
(:mod:`gaitscope.estimators._lock_batch`: supervisor, pipeline, ``tbe`` and the torque rule); as published,
:meth:`GaitStatePipeline.run <gaitscope.estimators.pipeline.GaitStatePipeline.run>`. The supervised fast path
covers the stack :func:`replay_stack` builds (``phase_ekf`` then ``tbe``, any pipeline and supervisor settings);
it hands over to stepping the stack, from the trial's start, where the stack would mark an estimator failed
(a non-finite output or covariance: the step path reports it as a session would), and a stack it does not
cover (other estimators, a primary other than ``phase_ekf``) is stepped throughout.

Not in a replay: a live session's soft start and intent boost (:class:`~gaitscope.sessions.estimation.FrameEstimator`),
which ramp the assistance a person receives; a replay shows the command at the given gain from the first sample.

:func:`run` and :func:`measurements` are the studies' path (the cross-validation reproduces seed 000): the heel
positions high-passed over the whole trial (seed 000 II-B, at the median sample period) and the pipeline run in
one compiled call.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from gaitscope.estimators.basis import Array
from gaitscope.estimators.highpass import HighPassFilter
from gaitscope.estimators.lock import LockConfig
from gaitscope.estimators.phase_ekf_estimator import PhaseEKFEstimator
from gaitscope.estimators.pipeline import GaitStatePipeline, PipelineConfig, TrainedModel
from gaitscope.estimators.protocol import ANGLE_CHANNELS, HEEL_STRIKE
from gaitscope.estimators.tbe import TimingBasedEstimator
from gaitscope.sessions import schema
from gaitscope.sessions.estimation import backward_difference
from gaitscope.sessions.formats.replay_io import ReplayInput, ReplayOutput, read_replay_csv
from gaitscope.sessions.registry import DERIVERS, ESTIMATORS, StackContext, feeds
from gaitscope.sessions.stack import EstimatorStack

if TYPE_CHECKING:
    from gaitscope.estimators._lock_batch import LockBatch

_VELOCITY_OF = {"foot_vel_dps": "foot_angle_deg", "shank_vel_dps": "shank_angle_deg"}


@dataclass(frozen=True)
class ReplaySummary:
    """What a replay did, for the command line and for logs."""

    samples: int
    duration_s: float
    heel_strikes: int
    heel_strikes_detected: bool
    backup_resets: int
    mean_phase_rate: float
    mean_stride_length_m: float
    incline_range_deg: tuple[float, float]
    peak_torque_Nm: float
    channels: tuple[str, ...]
    wall_s: float
    #: with the lock supervisor (a live session's ``phase_ekf``); else seed 000's filter as published
    supervised: bool = False
    standing_s: float = 0.0
    lost: int = 0
    #: what the stack reported for a session's event log (an estimator that failed, the torque handed on)
    events: tuple[str, ...] = ()
    #: the file's columns that are not channels (not read)
    ignored: tuple[str, ...] = ()
    #: registered estimators the file's channels cannot feed, with what each lacks (the registry's rule)
    cannot_feed: tuple[str, ...] = ()

    def lines(self) -> list[str]:
        src = "detected from the foot signals" if self.heel_strikes_detected else "from the input"
        return [
            f"samples          {self.samples} over {self.duration_s:.1f} s",
            f"channels         {', '.join(self.channels)}",
            f"heel strikes     {self.heel_strikes} ({src}); backup resets {self.backup_resets}",
            (
                f"supervisor       standing still {self.standing_s:.1f} s; lost track {self.lost} times"
                if self.supervised
                else "supervisor       off (seed 000's filter as published)"
            ),
            f"phase rate       mean {self.mean_phase_rate:.3f} /s ({60 * self.mean_phase_rate:.1f} /min)",
            f"stride length    mean {self.mean_stride_length_m:.3f} m",
            f"incline          {self.incline_range_deg[0]:.1f} .. {self.incline_range_deg[1]:.1f} deg",
            f"peak torque      {self.peak_torque_Nm:.1f} N m",
            f"wall time        {self.wall_s:.2f} s ({self.samples / max(self.wall_s, 1e-9):,.0f} samples/s)",
            *(f"event            {e}" for e in self.events),
            *([f"ignored          {', '.join(self.ignored)} (not channels)"] if self.ignored else []),
            *([f"cannot feed      {'; '.join(self.cannot_feed)}"] if self.cannot_feed else []),
        ]


def measurements(data: ReplayInput, highpass: bool = True) -> Array:
    """``(n, 6)`` measurement matrix in the EKF's channel order; NaN for absent channels.

    Values outside :data:`~gaitscope.sessions.schema.SENSOR_LIMITS` are missing (as live). Velocities absent
    from the input are derived from their angles; heel positions are high-passed, with a missing
    sample holding the filter's input at the last good value (its output there stays missing);
    ``highpass=False`` leaves them raw (for :class:`PhaseEKFEstimator`, which filters them as it goes).
    """
    n = data.time_s.size
    z = np.full((n, len(schema.REPLAY_SIGNALS)), np.nan)
    for i, name in enumerate(schema.REPLAY_SIGNALS):
        lo, hi = schema.SENSOR_LIMITS[name]
        if name in data.signals:
            v = data.signals[name]
            z[:, i] = np.where((v >= lo) & (v <= hi), v, np.nan)
        elif name in _VELOCITY_OF and _VELOCITY_OF[name] in data.signals:  # derived as a live session does
            a_lo, a_hi = schema.SENSOR_LIMITS[_VELOCITY_OF[name]]
            a = data.signals[_VELOCITY_OF[name]]
            z[:, i] = backward_difference(np.where((a >= a_lo) & (a <= a_hi), a, np.nan), data.time_s)
    if not highpass:
        return z
    heel = z[:, 4:6]
    dt = float(np.median(np.diff(data.time_s)))
    for j in range(2):
        good = np.isfinite(heel[:, j])
        if not good.any():
            continue
        held = heel[:, j].copy()
        idx = np.where(good, np.arange(n), 0)
        np.maximum.accumulate(idx, out=idx)
        held = held[idx]
        held[: int(np.argmax(good))] = held[int(np.argmax(good))]  # before the first good sample
        heel[:, j] = np.where(good, HighPassFilter(dt).filter(held), np.nan)
    return z


#: Samples per part of a replay: the output of one part is formatted while the next is estimated.
PART = 8192


def run(
    data: ReplayInput, model: TrainedModel, config: PipelineConfig, batch: bool = True
) -> tuple[dict[str, Array], int]:
    """Run the pipeline over a whole trial; returns the output columns and the backup's reset count.

    ``batch`` runs it in one compiled call; False calls :meth:`GaitStatePipeline.step` per sample (the
    same numbers, several times slower: for benchmarks and tests).
    """
    pipe, z, out = _start(data, model, config)
    return out, _estimate(pipe, data, z, out, 0, data.time_s.size, batch)


def replay_stack(
    model: TrainedModel, config: PipelineConfig, sample_period: float, lock: LockConfig | None = None
) -> EstimatorStack:
    """The estimator stack a replay runs: a live session's stack of ``phase_ekf`` (primary) and ``tbe``.

    As :func:`~gaitscope.sessions.registry.build_stack` builds it for a session with those estimators (in
    registry order, ``tbe`` timing the heel strikes ``phase_ekf`` finds; the torque profile of ``model``, the
    subject and the assistance of ``config``), except that ``phase_ekf`` takes all of ``config``'s filter
    settings and ``lock``'s supervisor thresholds (``LockConfig(enabled=False)``: seed 000's filter as published).
    """
    ctx = StackContext(model, config.leg_length, config.body_mass_kg, sample_period)
    ekf = PhaseEKFEstimator(model, config, sample_period, lock)
    return EstimatorStack(
        [ekf, ESTIMATORS["tbe"](ctx)],
        model.torque,
        ctx.leg_length,
        ctx.mass_kg,
        primary=ekf.name,
        torque_gain=config.torque_gain,
        max_torque=config.max_torque,
    )


def replay_file(
    input_path: str | Path,
    output_path: str | Path,
    model: TrainedModel,
    config: PipelineConfig,
    batch: bool = True,
    supervised: bool = False,
    lock: LockConfig | None = None,
) -> ReplaySummary:
    """Replay ``input_path`` into ``output_path``; nothing is written if the input is invalid.

    ``supervised``: the module docstring (``lock``: its thresholds); ``batch``: the stack's compiled fast path
    (False steps the stack, the same bytes ten times slower: for benchmarks and tests). The output is written
    in parts of :data:`PART` samples, each formatted while the next is estimated."""
    start = time.perf_counter()
    data = read_replay_csv(input_path)
    n = data.time_s.size
    parts: _Stacked | _Compiled | _Supervised
    if supervised and batch:
        parts = _Supervised(data, model, config, lock)
    elif not batch:
        parts = _Stacked(data, model, config, lock if supervised else LockConfig(enabled=False))
    else:
        parts = _Compiled(data, model, config)
    out = {k: np.empty(n) for k in schema.REPLAY_OUTPUT}
    out["time_s"][:] = data.time_s
    resets = 0
    with ReplayOutput(output_path) as output:
        for a in range(0, n, PART):
            b = min(a + PART, n)
            resets += parts.estimate(out, a, b)
            output.add({k: v[a:b] for k, v in out.items()})
    wall = time.perf_counter() - start
    stacked = parts if isinstance(parts, _Stacked | _Supervised) else None
    return ReplaySummary(
        samples=n,
        duration_s=float(data.time_s[-1] - data.time_s[0]),
        heel_strikes=int(out["heel_strike"].sum()),
        heel_strikes_detected=data.heel_strike is None,
        backup_resets=resets,
        mean_phase_rate=float(out["phase_rate"].mean()),
        mean_stride_length_m=float(out["stride_length_m"].mean()),
        incline_range_deg=(float(out["incline_deg"].min()), float(out["incline_deg"].max())),
        peak_torque_Nm=float(out["torque_Nm"].max()),
        channels=tuple(sorted(data.signals)),
        wall_s=wall,
        supervised=supervised,
        standing_s=0.0 if stacked is None else stacked.standing_s,
        lost=0 if stacked is None else stacked.lost,
        events=() if stacked is None else tuple(stacked.events),
        ignored=data.ignored,
        cannot_feed=_cannot_feed(data),
    )


def _cannot_feed(data: ReplayInput) -> tuple[str, ...]:
    """The registered estimators (not the IMU front ends) the file cannot feed, each with what it lacks (an
    angle's velocity left out when the angle is missing too: it would be derived from it)."""
    derived_from = {vel: angle for angle, vel in ANGLE_CHANNELS.items()}
    out = []
    for name, feed in feeds(data.signals).items():
        if feed.missing and name not in DERIVERS:
            lacks = [c for c in feed.missing if derived_from.get(c) not in feed.missing]
            out.append(f"{name} needs {', '.join(lacks)}")
    return tuple(out)


def _period(data: ReplayInput) -> float:
    """The trial's nominal sample period (s): the median one."""
    return float(np.median(np.diff(data.time_s))) if data.time_s.size > 1 else 0.01


def _start(
    data: ReplayInput, model: TrainedModel, config: PipelineConfig
) -> tuple[GaitStatePipeline, Array, dict[str, Array]]:
    """The pipeline for a trial (heel filter at its median sample period), its measurements and the
    output columns to fill (``time_s`` filled)."""
    z = measurements(data)
    pipe = GaitStatePipeline(model, config, sample_period=float(np.median(np.diff(data.time_s))))
    out = {k: np.empty(data.time_s.size) for k in schema.REPLAY_OUTPUT}
    out["time_s"][:] = data.time_s
    return pipe, z, out


def _estimate(
    pipe: GaitStatePipeline, data: ReplayInput, z: Array, out: dict[str, Array], a: int, b: int, batch: bool
) -> int:
    """Samples ``a`` to ``b`` through the pipeline into ``out``; returns the backup's resets among them."""
    hs_in = data.heel_strike
    if batch:
        est = pipe.run(data.time_s[a:b], z[a:b], None if hs_in is None else hs_in[a:b], heel_filtered=True)
        for column in schema.REPLAY_OUTPUT[1:]:
            out[column][a:b] = est[column]
        return int(est["backup_reset"].sum())
    resets = 0
    for k in range(a, b):
        hs = None if hs_in is None else bool(hs_in[k])
        e = pipe.step(float(data.time_s[k]), z[k], hs, heel_filtered=True)
        out["phase"][k] = e.phase
        out["phase_rate"][k] = e.phase_rate
        out["stride_length_m"][k] = e.stride_length_m
        out["incline_deg"][k] = e.incline_deg
        out["torque_Nm"][k] = e.torque_Nm
        out["heel_strike"][k] = e.heel_strike
        out["tbe_phase"][k] = e.tbe_phase
        resets += e.backup_reset
    return resets


class _Stacked:
    """A trial through :func:`replay_stack`, part by part, as a device streams it."""

    def __init__(self, data: ReplayInput, model: TrainedModel, config: PipelineConfig, lock: LockConfig | None):
        self.data = data
        self.z = measurements(data, highpass=False)  # raw heel positions: phase_ekf filters them as it goes
        self.stack = replay_stack(model, config, _period(data), lock)
        self._ekf = self.stack.names.index(PhaseEKFEstimator.name)
        self._standing = self.stack.outputs[self._ekf].index("standing")
        self._t: float | None = None
        #: time the supervisor held the walker standing, full weight (s); lock losses; the stack's events
        self.standing_s, self.lost = 0.0, 0
        self.events: list[str] = []

    def estimate(self, out: dict[str, Array], a: int, b: int) -> int:
        """Samples ``a`` to ``b`` into ``out``; returns the primary's backup resets among them."""
        step, names, ekf, standing = self.stack.step, schema.REPLAY_SIGNALS, self._ekf, self._standing
        t = self.data.time_s[a:b].tolist()
        rows = self.z[a:b].tolist()
        hs_in = self.data.heel_strike
        given = [math.nan] * (b - a) if hs_in is None else hs_in[a:b].astype(np.float64).tolist()
        columns: tuple[list[float], ...] = tuple([] for _ in range(7))
        phase, rate, stride, incline, torque, hs, tbe = columns
        resets, nan = 0, math.nan
        for k, tk in enumerate(t):
            channels = dict(zip(names, rows[k], strict=True))
            channels[HEEL_STRIKE] = given[k]
            e = step(tk, channels)
            # not estimated (None): NaN in the replay's columns
            phase.append(nan if e.phase is None else e.phase)
            rate.append(nan if e.phase_rate is None else e.phase_rate)
            stride.append(nan if e.stride_length_m is None else e.stride_length_m)
            incline.append(nan if e.incline_deg is None else e.incline_deg)
            torque.append(e.torque_Nm)
            hs.append(e.heel_strike)
            tbe.append(nan if e.tbe_phase is None else e.tbe_phase)
            resets += e.backup_reset
            self.lost += e.fault == "lost"
            if e.events:
                self.events.extend(e.events)
            y = e.outputs[ekf]
            if y is not None and y[standing] >= 1.0 and self._t is not None:
                self.standing_s += tk - self._t
            self._t = tk
        for name, values in zip(schema.REPLAY_OUTPUT[1:], columns, strict=True):
            out[name][a:b] = values
        return resets


class _Compiled:
    """The stack's fast path without the supervisor: :meth:`GaitStatePipeline.run`, one compiled call per part,
    equal to :class:`_Stacked` bit for bit (the same heel high-pass as it goes, the same torque rule)."""

    def __init__(self, data: ReplayInput, model: TrainedModel, config: PipelineConfig):
        self.data = data
        self.z = measurements(data, highpass=False)
        self.pipe = GaitStatePipeline(model, config, sample_period=_period(data))

    def estimate(self, out: dict[str, Array], a: int, b: int) -> int:
        """Samples ``a`` to ``b`` into ``out``; returns the backup's resets among them."""
        hs_in = self.data.heel_strike
        est = self.pipe.run(self.data.time_s[a:b], self.z[a:b], None if hs_in is None else hs_in[a:b])
        for column in schema.REPLAY_OUTPUT[1:]:
            out[column][a:b] = est[column]
        return int(est["backup_reset"].sum())


def compiled_stack(stack: EstimatorStack) -> LockBatch | None:
    """The compiled loop of a fresh stack of ``phase_ekf`` (primary) then ``tbe``, as :func:`replay_stack` makes
    it (None for any other stack, which is then stepped)."""
    from gaitscope.estimators._lock_batch import LockBatch  # numba's compiled code: loaded when replayed

    ekf, *others = stack.estimators
    if (
        stack.names != (PhaseEKFEstimator.name, TimingBasedEstimator.name)
        or type(ekf) is not PhaseEKFEstimator
        or type(others[0]) is not TimingBasedEstimator
        or stack.primary != PhaseEKFEstimator.name
        or stack.failed
        or stack._t is not None
    ):
        return None
    return LockBatch(
        ekf, others[0], stack.torque, stack.leg_length, stack.mass_kg, stack.torque_gain, stack.max_torque,
        stack.max_variance,
    )  # fmt: skip


class _Supervised:
    """:func:`replay_stack`'s stack with the supervisor on its compiled path (:func:`compiled_stack`), one call per
    part, equal to :class:`_Stacked` bit for bit; :class:`_Stacked` from the trial's start where the compiled path
    stops (a sample on which the stack would mark an estimator failed) or for a stack it does not cover."""

    def __init__(self, data: ReplayInput, model: TrainedModel, config: PipelineConfig, lock: LockConfig | None):
        self.data, self._model, self._config, self._lock = data, model, config, lock
        self.z = measurements(data, highpass=False)
        self.batch = compiled_stack(replay_stack(model, config, _period(data), lock))
        hs_in = data.heel_strike
        self.given = np.full(data.time_s.size, np.nan) if hs_in is None else hs_in.astype(np.float64)
        self.stepped: _Stacked | None = None if self.batch is not None else _Stacked(data, model, config, lock)

    @property
    def standing_s(self) -> float:
        return self.stepped.standing_s if self.stepped is not None else self.batch.standing_s if self.batch else 0.0

    @property
    def lost(self) -> int:
        return self.stepped.lost if self.stepped is not None else self.batch.lost if self.batch else 0

    @property
    def events(self) -> list[str]:
        return self.stepped.events if self.stepped is not None else []

    def estimate(self, out: dict[str, Array], a: int, b: int) -> int:
        """Samples ``a`` to ``b`` into ``out``; returns the primary's backup resets among them."""
        if self.stepped is None and self.batch is not None:
            columns, hs = np.empty((b - a, 6)), np.empty(b - a, dtype=np.bool_)
            resets = self.batch.backup_resets
            failed = self.batch.run(self.data.time_s[a:b], self.z[a:b], self.given[a:b], columns, hs)
            if failed < 0:
                for j, name in enumerate(("phase", "phase_rate", "stride_length_m", "incline_deg", "torque_Nm")):
                    out[name][a:b] = columns[:, j]
                out["tbe_phase"][a:b] = columns[:, 5]
                out["heel_strike"][a:b] = hs
                return self.batch.backup_resets - resets
            # the stack marks an estimator failed in this part: step the trial from its start (the same numbers
            # up to here), so that the failure is handled and reported as the stack does
            self.stepped = _Stacked(self.data, self._model, self._config, self._lock)
            self.stepped.estimate({k: np.empty(a) for k in schema.REPLAY_OUTPUT}, 0, a)
        assert self.stepped is not None
        return self.stepped.estimate(out, a, b)
