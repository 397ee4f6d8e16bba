"""A/B review: two or more re-runs of one trial side by side, with the figures a clinician compares.

Each run is a full-rate re-run (:func:`~gaitscope.sessions.review.rerun.rerun_series` with every row kept, which is
why a comparison is bounded by :data:`MAX_ROWS` samples: zoom to a window for a longer trial). All runs
step through the same recorded frames, so their rows are on the same session times; the comparison
aligns them on ``seq`` and keeps the rows present in every run.

Per run (:func:`run_figures`): the complete strides (each run's own heel strikes, 0.3-4 s long), the
mean of each stride's peak torque command (N·m), the mean estimated phase rate (1/s) and stride length
(m); with a ground truth (:func:`simulated_truth`: a simulated session's walk, regenerated from its
seed), the RMS errors of phase (% of a cycle, wrapped), phase rate, stride length and incline.
Against the first run (the reference, "A"): the torque and phase differences over time. A run as recorded
resumes from the estimation state recorded at the trial's start, so a baseline "what ran" is exactly what ran
(each run's ``start`` says how its estimators began). The mean
stride (:func:`stride_mean`): torque per % of the stride, mean and SD across strides.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.formats.mcap_io import count_messages, read_messages, series_window
from gaitscope.sessions.review.rerun import START_KEY, rerun_series
from gaitscope.sessions.schema import (
    ComparedRun,
    ComparedRunSpec,
    Comparison,
    RunFigures,
    SimulatedSource,
)

__all__ = [
    "MAX_ROWS",
    "STRIDE_POINTS",
    "Truth",
    "WindowTooLong",
    "compare",
    "run_figures",
    "simulated_truth",
    "stride_mean",
]

#: Most samples one comparison re-runs per run (6 minutes at 200 Hz): every row of each run is held.
MAX_ROWS: Final = 72_000
#: Points of a mean stride (0, 1, ..., 100 % of the stride).
STRIDE_POINTS: Final = 101
#: A stride counts when it lasts this long (s), as the browser's stride overlay counts them.
MIN_STRIDE_S: Final = 0.3
MAX_STRIDE_S: Final = 4.0

F64 = NDArray[np.float64]


class WindowTooLong(ValueError):
    """A comparison asked over more samples than :data:`MAX_ROWS`."""


@dataclass(frozen=True)
class Truth:
    """The ground truth at each compared row: phase (0..1), phase rate (1/s), stride length (m), incline (deg)."""

    source: str
    phase: F64
    phase_rate: F64
    stride_length_m: F64
    incline_deg: F64


def _f64(values: Sequence[Any]) -> F64:
    return np.array([np.nan if v is None else float(v) for v in values], dtype=np.float64)


def _strides(t: F64, heel_strike: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """``(i0, i1)`` index pairs (``i1`` inclusive) of the complete strides between consecutive heel strikes."""
    hs = np.flatnonzero(heel_strike)
    out = []
    for a, b in itertools.pairwise(hs):
        if MIN_STRIDE_S <= t[b] - t[a] <= MAX_STRIDE_S and b - a >= 4:
            out.append((int(a), int(b)))
    return out


def _mean(x: F64) -> float | None:
    x = x[np.isfinite(x)]
    return float(x.mean()) if x.size else None


def _rms(err: F64) -> float | None:
    err = err[np.isfinite(err)]
    return float(np.sqrt(np.mean(err**2))) if err.size else None


def _wrap(d: F64) -> F64:
    """A phase difference (cycles) wrapped to [-0.5, 0.5)."""
    return (d + 0.5) % 1.0 - 0.5


def run_figures(
    t: F64, torque: F64, phase: F64, phase_rate: F64, stride_length: F64, incline: F64,
    heel_strike: NDArray[np.bool_], truth: Truth | None = None,
) -> RunFigures:  # fmt: skip
    """A run's figures (see the module docstring); all arrays row for row."""
    strides = _strides(t, heel_strike)
    peaks = np.array(
        [np.nanmax(torque[a : b + 1]) if np.isfinite(torque[a : b + 1]).any() else np.nan for a, b in strides]
    )
    figures = RunFigures(
        strides=len(strides),
        peak_torque_Nm=_mean(peaks) if peaks.size else None,
        mean_phase_rate_1_s=_mean(phase_rate),
        mean_stride_length_m=_mean(stride_length),
    )
    if truth is None:
        return figures
    return figures.model_copy(
        update={
            "phase_rmse_pct": None if (e := _rms(_wrap(phase - truth.phase))) is None else 100.0 * e,
            "phase_rate_rmse_1_s": _rms(phase_rate - truth.phase_rate),
            "stride_length_rmse_m": _rms(stride_length - truth.stride_length_m),
            "incline_rmse_deg": _rms(incline - truth.incline_deg),
        }
    )


def stride_mean(t: F64, y: F64, heel_strike: NDArray[np.bool_], points: int = STRIDE_POINTS) -> tuple[F64, F64, int]:
    """Mean and SD (across strides) of ``y`` resampled to ``points`` equally spaced % of each complete
    stride (linear interpolation in time), and the number of strides; NaN everywhere without a stride."""
    strides = _strides(t, heel_strike)
    if not strides:
        return np.full(points, np.nan), np.full(points, np.nan), 0
    rows = np.empty((len(strides), points))
    for k, (a, b) in enumerate(strides):
        ts = t[a : b + 1]
        grid = np.linspace(ts[0], ts[-1], points)
        rows[k] = np.interp(grid, ts, y[a : b + 1])
    sd = rows.std(axis=0, ddof=1) if len(strides) > 1 else np.zeros(points)
    return rows.mean(axis=0), sd, len(strides)


def _keep(columns: Sequence[F64], n: int, max_points: int) -> NDArray[np.intp]:
    """Rows kept of ``n``: all when ``n <= max_points``, else per bucket the first row and each column's
    minimum and maximum, so that no series loses its peaks."""
    if n <= max_points:
        return np.arange(n)
    per = 1 + 2 * max(len(columns), 1)
    buckets = max(1, max_points // per)
    edges = np.linspace(0, n, buckets + 1).round().astype(int)
    keep: set[int] = set()
    for a, b in itertools.pairwise(edges):
        if b <= a:
            continue
        keep.add(int(a))
        for y in columns:
            seg = y[a:b]
            if np.isfinite(seg).any():
                keep.add(int(a + np.nanargmin(seg)))
                keep.add(int(a + np.nanargmax(seg)))
    return np.array(sorted(keep), dtype=np.intp)


def _list(x: F64) -> list[float | None]:
    return [None if not np.isfinite(v) else float(v) for v in x.tolist()]


def compare(
    path: Path,
    models: Callable[[str], TrainedModel],
    leg_length: float,
    mass_kg: float,
    runs: Sequence[ComparedRunSpec],
    t0: float | None = None,
    t1: float | None = None,
    max_points: int = 2000,
    fingerprint: Sequence[float] | None = None,
    truth: Callable[[NDArray[np.int64]], Truth | None] | None = None,
) -> Comparison:
    """Re-run the trial once per run and compare them (see the module docstring).

    Args:
        path: the trial's MCAP file.
        models, leg_length, mass_kg, fingerprint: as :func:`~gaitscope.sessions.review.rerun.rerun_series`.
        runs: the runs, the first the reference.
        t0, t1: the session-time window compared (s; None: unbounded).
        max_points: about how many rows of the time series come back (decimated keeping extremes).
        truth: the ground truth at the rows' ``seq`` values, or None when the trial has none.

    Raises:
        WindowTooLong: the window holds more than :data:`MAX_ROWS` samples.
        DataFormatError: the window holds no sample; and what
            :func:`~gaitscope.sessions.review.rerun.rerun_series` raises.
    """
    window = series_window(path, t0, t1)
    n = 0 if window is None else count_messages(path, "/sensor", *window)
    if n > MAX_ROWS:
        raise WindowTooLong(
            f"this window holds {n} samples; an A/B comparison re-runs at most {MAX_ROWS} "
            f"(zoom to a shorter part of the trial, for example {MAX_ROWS // 200 // 60} minutes at 200 Hz)"
        )
    results = []
    for spec in runs:
        series = rerun_series(
            path, models, leg_length, mass_kg, spec.settings, t0, t1, MAX_ROWS, spec.estimators, fingerprint
        )
        if not series.get("t"):
            raise DataFormatError("the trial holds no sensor frames in this window to re-run", file=path.name)
        results.append(series)
    # align on seq: the rows every run has
    common = set(results[0]["seq"])
    for r in results[1:]:
        common &= set(r["seq"])
    seqs = np.array(sorted(common), dtype=np.int64)
    starts = [str(r[START_KEY][0]) for r in results]
    cols: list[dict[str, Any]] = []
    for r in results:
        index = {s: i for i, s in enumerate(r["seq"])}
        rows = np.array([index[int(s)] for s in seqs], dtype=np.intp)
        cols.append(
            {
                k: _f64([r[k][i] for i in rows])
                for k in ("t", "torque_Nm", "phase", "phase_rate", "stride_length_m", "incline_deg")
            }
            | {"heel_strike": np.array([bool(r["heel_strike"][i]) for i in rows])}
        )
    t = cols[0]["t"]
    known = truth(seqs) if truth is not None else None
    ref = cols[0]
    diffs = [(c["torque_Nm"] - ref["torque_Nm"], 100.0 * _wrap(c["phase"] - ref["phase"])) for c in cols]
    keep = _keep([x for c, d in zip(cols, diffs, strict=True) for x in (c["torque_Nm"], *d)], len(t), max_points)
    out = []
    for spec, c, (dtorque, dphase), start in zip(runs, cols, diffs, starts, strict=True):
        mean, sd, _ = stride_mean(c["t"], c["torque_Nm"], c["heel_strike"])
        figures = run_figures(
            c["t"], c["torque_Nm"], c["phase"], c["phase_rate"], c["stride_length_m"], c["incline_deg"],
            c["heel_strike"], known,
        )  # fmt: skip
        out.append(
            ComparedRun(
                name=spec.name,
                figures=figures,
                torque_Nm=_list(c["torque_Nm"][keep]),
                phase_pct=_list(100.0 * c["phase"][keep]),
                torque_diff_Nm=_list(dtorque[keep]),
                phase_diff_pct=_list(dphase[keep]),
                stride_torque_mean_Nm=_list(mean),
                stride_torque_sd_Nm=_list(sd),
                start=start,
            )
        )
    return Comparison(
        t=[float(x) for x in t[keep]],
        stride_pct=np.linspace(0.0, 100.0, STRIDE_POINTS).tolist(),
        ground_truth=None if known is None else known.source,
        runs=out,
    )


def simulated_truth(spec: SimulatedSource, path: Path) -> Callable[[NDArray[np.int64]], Truth]:
    """The ground truth of a trial recorded from a simulated session: its walk regenerated from the spec
    (deterministic from its seed), the recorded frame ``seq`` counting its rows pass after pass (a looped
    walk starts again at row 0).

    Raises:
        DataFormatError: the recording's frames do not match the regenerated walk (another spec).
    """
    from gaitscope.sessions.synth.trials import sensor_trial

    schedule = [(p.speed_m_s, p.incline_deg, p.strides) for p in spec.protocol]
    walk, _, _ = sensor_trial(schedule, subject=spec.cohort_subject, rate_hz=spec.rate_hz, seed=spec.seed)
    n = len(walk)
    # check: the first recorded frame's foot angle is the walk's at its row
    for _, _, msg in read_messages(path, ["/sensor"]):
        if isinstance(msg, dict) and isinstance(msg.get("seq"), int) and msg.get("foot_angle_deg") is not None:
            expected = float(walk["foot_angle_deg"].iloc[msg["seq"] % n])
            if abs(expected - float(msg["foot_angle_deg"])) > 1e-6:
                raise DataFormatError("the recording's frames are not its session's simulated walk", file=str(path))
        break
    columns = {
        c: walk[c].to_numpy(np.float64) for c in ("gt_phase", "gt_phase_rate", "gt_stride_length_m", "gt_incline_deg")
    }
    source = f"the simulated walk (cohort subject {spec.cohort_subject}, seed {spec.seed})"

    def at(seqs: NDArray[np.int64]) -> Truth:
        rows = np.asarray(seqs, dtype=np.int64) % n
        return Truth(
            source=source,
            phase=columns["gt_phase"][rows],
            phase_rate=columns["gt_phase_rate"][rows],
            stride_length_m=columns["gt_stride_length_m"][rows],
            incline_deg=columns["gt_incline_deg"][rows],
        )

    return at
