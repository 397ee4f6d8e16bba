"""Replay a recorded trial (the replay CSV) through the estimator stack.

Reads the input with full validation (:mod:`gaitscope.sessions.formats.replay_io`), derives missing angular velocities
from the angles (``numpy.gradient`` in time), high-passes the raw heel positions over the whole trial
(seed 000 II-B, discretised at the median sample period), runs :class:`GaitStatePipeline` over the
whole trial in one compiled call (:meth:`~GaitStatePipeline.run`, the same outputs as stepping it sample
by sample as a live device does; ``batch=False`` steps it, for comparison) and writes the output
atomically.

``supervised=True`` (what ``gaitscope replay`` and ``gaitscope demo`` do unless ``--as-published``)
runs the filter as a live session's ``phase_ekf`` does instead: sample by sample through
:class:`~gaitscope.estimators.phase_ekf_estimator.PhaseEKFEstimator`, with its lock supervisor
(:mod:`gaitscope.estimators.lock`: standing still, heel strikes from the shank, lock loss), the torque times
``1 - standing`` and 0 at a lock-loss reset, as the session's stack commands it. The compiled path
stays seed 000's filter as published, which the cross-validation reproduces.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gaitscope.estimators.basis import Array
from gaitscope.estimators.highpass import HighPassFilter
from gaitscope.estimators.lock import LockConfig
from gaitscope.estimators.phase_ekf_estimator import PhaseEKFEstimator
from gaitscope.estimators.pipeline import GaitStatePipeline, PipelineConfig, TrainedModel
from gaitscope.estimators.protocol import FAULTS
from gaitscope.sessions import schema
from gaitscope.sessions.formats.replay_io import ReplayInput, ReplayOutput, read_replay_csv

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
        elif name in _VELOCITY_OF and _VELOCITY_OF[name] in data.signals:
            a_lo, a_hi = schema.SENSOR_LIMITS[_VELOCITY_OF[name]]
            a = data.signals[_VELOCITY_OF[name]]
            with np.errstate(invalid="ignore", over="ignore"):
                v = np.gradient(np.where((a >= a_lo) & (a <= a_hi), a, np.nan), data.time_s)
            z[:, i] = np.where((v >= lo) & (v <= hi), v, np.nan)
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

    ``batch``: see :func:`run`; ``supervised``: the module docstring (``lock``: its thresholds). The
    output is written in parts of :data:`PART` samples, each formatted while the next is estimated."""
    start = time.perf_counter()
    data = read_replay_csv(input_path)
    pipe, z, out = _start(data, model, config)
    n = data.time_s.size
    resets = 0
    sup = _Supervised(data, model, config, lock) if supervised else None
    with ReplayOutput(output_path) as output:
        for a in range(0, n, PART):
            b = min(a + PART, n)
            resets += _estimate(pipe, data, z, out, a, b, batch) if sup is None else sup.estimate(out, a, b)
            output.add({k: v[a:b] for k, v in out.items()})
    wall = time.perf_counter() - start
    return ReplaySummary(
        samples=data.time_s.size,
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
        supervised=sup is not None,
        standing_s=0.0 if sup is None else sup.standing_s,
        lost=0 if sup is None else sup.lost,
    )


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


class _Supervised:
    """A live session's ``phase_ekf`` over a trial, part by part: outputs as :func:`_estimate` writes them."""

    def __init__(self, data: ReplayInput, model: TrainedModel, config: PipelineConfig, lock: LockConfig | None):
        self.data, self.model, self.config = data, model, config
        self.z = measurements(data, highpass=False)
        period = float(np.median(np.diff(data.time_s))) if data.time_s.size > 1 else 0.01
        self.est = PhaseEKFEstimator(model, config, period, lock)
        self.standing_s, self.lost = 0.0, 0
        self._names = [name for name, _ in PhaseEKFEstimator.outputs]

    def estimate(self, out: dict[str, Array], a: int, b: int) -> int:
        """Samples ``a`` to ``b`` into ``out``; returns the backup's resets among them."""
        col = {name: i for i, name in enumerate(self._names)}
        cfg, hs_in, t = self.config, self.data.heel_strike, self.data.time_s
        z = np.empty(7)
        resets = 0
        for k in range(a, b):
            z[:6] = self.z[k]
            z[6] = np.nan if hs_in is None else float(hs_in[k])
            y = self.est.step(float(t[k]), z)
            still = float(y[col["standing"]])
            fault = float(y[col["fault"]])
            command = self.model.torque.torque_at(
                float(y[col["phase"]]),
                float(y[col["stride_length_m"]]) / cfg.leg_length,
                float(y[col["incline_deg"]]),
                cfg.body_mass_kg * cfg.torque_gain,
                cfg.max_torque,
            )
            lost = fault == FAULTS.index("lost")
            out["phase"][k] = y[col["phase"]]
            out["phase_rate"][k] = y[col["phase_rate"]]
            out["stride_length_m"][k] = y[col["stride_length_m"]]
            out["incline_deg"][k] = y[col["incline_deg"]]
            out["torque_Nm"][k] = 0.0 if lost or fault == FAULTS.index("diverged") else command * (1.0 - still)
            out["heel_strike"][k] = y[col["heel_strike"]]
            out["tbe_phase"][k] = self.est.pipeline.tbe.phase
            resets += int(y[col["backup_reset"]] > 0.5)
            self.lost += int(lost)
            if still >= 1.0 and k > 0:
                self.standing_s += float(t[k] - t[k - 1])
        return resets
