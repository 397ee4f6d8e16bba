"""A stopped session's summary (:class:`~gaitscope.sessions.schema.SessionSummary`) from its rows and recordings.

Strides run from one heel strike (``GaitState.heel_strike``) to the next. A stride's speed is the
estimated stride length at its end over its duration, its incline the mean estimated incline over it.
Strides shorter than :data:`MIN_STRIDE_S`, longer than :data:`MAX_STRIDE_S` (standing, a gap) or holding a
fault (the filters were reset, the torque forced to 0) are left out of the profile and the overlays.
A condition is a speed rounded to :data:`SPEED_BIN` m/s and an incline rounded to :data:`INCLINE_BIN`
degrees: its curves are each signal resampled over the stride at :data:`POINTS` points (0-100 %).
"""

from __future__ import annotations

import itertools
import math
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np

from gaitscope.sessions import schema
from gaitscope.sessions.formats.mcap_io import count_messages, read_messages
from gaitscope.sessions.store import Store

__all__ = [
    "INCLINE_BIN",
    "MAX_STRIDE_S",
    "MIN_STRIDE_S",
    "OVERLAY_SIGNALS",
    "POINTS",
    "SETTING_NAMES",
    "SPEED_BIN",
    "TrialData",
    "read_trial",
    "session_summary",
    "setting_text",
]

MIN_STRIDE_S: Final = 0.4
MAX_STRIDE_S: Final = 3.0
SPEED_BIN: Final = 0.2
INCLINE_BIN: Final = 2.5
POINTS: Final = 51
#: Signals overlaid per condition, and their names on screen and in the report.
OVERLAY_SIGNALS: Final = {
    "torque_Nm": "Assistance torque (N·m)",
    "thigh_angle_deg": "Thigh angle (deg)",
    "shank_angle_deg": "Shank angle (deg)",
    "foot_angle_deg": "Foot angle (deg)",
}
_ANGLES: Final = ("thigh_angle_deg", "shank_angle_deg", "foot_angle_deg")
_COLUMNS: Final = ("t", "stride_length_m", "incline_deg", "torque_Nm", *_ANGLES)
_FLAGS: Final = ("heel_strike", "fault", "backup_reset")
_PROGRESS_ROWS: Final = 2000
#: Settings by the name a clinician reads.
SETTING_NAMES: Final = {
    "torque_gain": "Torque gain",
    "max_torque_Nm": "Torque limit (N·m)",
    "measurement_noise_scale": "Measurement noise scale",
    "process_noise_scale": "Process noise scale",
    "intent_gain_boost": "Assistance follows intent",
    "primary": "Estimator driving the torque",
    "model": "Gait model",
    "gp_ekf": "GP-EKF model",
}
_SOURCES: Final = {"simulated": "simulated walker", "replay": "replay of a trial", "device": "live device",
                   "upload": "uploaded recording"}  # fmt: skip


@dataclass(frozen=True)
class TrialData:
    """One trial's gait states as arrays (``columns`` of :data:`_COLUMNS` as float with NaN for missing,
    ``flags`` of :data:`_FLAGS` as bool), all of length ``n``."""

    trial: schema.Trial
    columns: dict[str, np.ndarray]
    flags: dict[str, np.ndarray]

    @property
    def n(self) -> int:
        return len(self.columns["t"])


def read_trial(trial: schema.Trial, path: Path, on_rows: Callable[[int], None] | None = None) -> TrialData:
    """The ``/gait_state`` messages of a trial's recording, as arrays; ``on_rows(n)`` is called after every
    :data:`_PROGRESS_ROWS` rows read (a long trial's progress)."""
    rows: dict[str, list[Any]] = {c: [] for c in (*_COLUMNS, *_FLAGS)}
    for n, (_, _, msg) in enumerate(read_messages(path, ["/gait_state"]), 1):
        if on_rows is not None and n % _PROGRESS_ROWS == 0:
            on_rows(n)
        for c in _COLUMNS:
            v = msg.get(c)
            rows[c].append(math.nan if v is None else float(v))
        for c in _FLAGS:
            rows[c].append(bool(msg.get(c)))
    return TrialData(
        trial,
        {c: np.asarray(rows[c], dtype=float) for c in _COLUMNS},
        {c: np.asarray(rows[c], dtype=bool) for c in _FLAGS},
    )


def setting_text(event: schema.Event) -> str:
    """A setting change in words: ``"Torque gain 1.00 -> 1.30, by clinician"`` (numbers with two decimals)."""
    name = SETTING_NAMES.get(event.field or "", (event.field or "setting").replace("_", " ").capitalize())

    def shown(v: float | str | None) -> str:
        if v is None:
            return "none"
        return f"{v:.2f}" if isinstance(v, float) else str(v)

    return f"{name} {shown(event.before)} -> {shown(event.after)}, by {event.actor}"


def _strides(data: TrialData) -> list[tuple[int, int]]:
    """Index ranges ``[i, j]`` (heel strike to next heel strike) of the trial's usable strides."""
    hs = np.flatnonzero(data.flags["heel_strike"])
    t = data.columns["t"]
    fault = data.flags["fault"]
    out = []
    for i, j in itertools.pairwise(hs):
        dt = t[j] - t[i]
        if MIN_STRIDE_S <= dt <= MAX_STRIDE_S and not fault[i:j].any():
            out.append((int(i), int(j)))
    return out


def _curve(data: TrialData, signal: str, i: int, j: int) -> np.ndarray:
    """The signal over samples ``i..j`` resampled at :data:`POINTS` points of the stride (NaN if missing)."""
    t = data.columns["t"][i : j + 1]
    y = data.columns[signal][i : j + 1]
    ok = np.isfinite(y)
    if ok.sum() < 2:
        return np.full(POINTS, np.nan)
    x = (t - t[0]) / (t[-1] - t[0])
    return np.interp(np.linspace(0.0, 1.0, POINTS), x[ok], y[ok])


def _nullable(a: np.ndarray, digits: int = 3) -> list[float | None]:
    return [None if not math.isfinite(v) else round(float(v), digits) for v in a]


def _bin(x: float, width: float) -> float:
    return round(round(x / width) * width, 3) + 0.0  # + 0.0: no "-0.0"


def _health(datas: list[TrialData], trials: list[schema.Trial]) -> schema.DataHealthFigures:
    samples = sum(d.n for d in datas)
    dts = [np.diff(d.columns["t"]) for d in datas if d.n > 1]
    dt = np.concatenate(dts) if dts else np.empty(0)
    period = float(np.median(dt)) if dt.size else math.nan
    gaps = dt[dt > 3 * period] if dt.size else dt
    missing = 0
    for d in datas:
        present = [c for c in _ANGLES if np.isfinite(d.columns[c]).any()]
        if present:
            missing += int(np.any([~np.isfinite(d.columns[c]) for c in present], axis=0).sum())
    return schema.DataHealthFigures(
        samples=samples,
        recorded_s=round(sum(float(d.columns["t"][-1] - d.columns["t"][0]) for d in datas if d.n > 1), 3),
        rate_hz=round(1.0 / period, 2) if dt.size and period > 0 else None,
        gaps=int(gaps.size),
        longest_gap_s=round(float(gaps.max()), 3) if gaps.size else 0.0,
        missing_percent=round(100.0 * missing / samples, 2) if samples else 0.0,
        faults=sum(int(d.flags["fault"].sum()) for d in datas),
        backup_resets=sum(int(d.flags["backup_reset"].sum()) for d in datas),
        trials_recovered=sum(t.status == "recovered" for t in trials),
        trials_damaged=sum(t.status == "damaged" for t in trials),
    )


def _duration(session: schema.Session, datas: list[TrialData]) -> float:
    import datetime as dt

    if session.started_utc and session.stopped_utc:
        start = dt.datetime.fromisoformat(session.started_utc.replace("Z", "+00:00"))
        stop = dt.datetime.fromisoformat(session.stopped_utc.replace("Z", "+00:00"))
        return round((stop - start).total_seconds(), 3)
    return round(sum(d.trial.duration_s for d in datas), 3)


def session_summary(
    store: Store, data_dir: Path, session_id: int, *, on_progress: Callable[[int, int], None] | None = None
) -> tuple[schema.SessionSummary, list[TrialData]]:
    """The summary of a session and the trial data it was made from (the exports reuse them).

    ``on_progress(done, total)`` is called as the recordings are read, in gait states (progress of a long
    export). Trials still recording or damaged are listed but not read.
    """
    from gaitscope.sessions.review.rerun import recorded_settings

    session = store.get_session(session_id)
    subject = store.get_subject(session.subject_id)
    trials = store.list_trials(session_id)
    readable = [t for t in trials if t.status not in ("recording", "damaged")]
    total = sum(count_messages(data_dir / t.path, "/gait_state", None, None) for t in readable) if on_progress else 0
    datas: list[TrialData] = []
    for trial in readable:
        before = sum(d.n for d in datas)
        report = None if on_progress is None else (lambda n, b=before: on_progress(b + n, total))
        datas.append(read_trial(trial, data_dir / trial.path, report))
        if on_progress is not None:
            on_progress(before + datas[-1].n, total)
    profile: list[schema.StrideProfilePoint] = []
    groups: dict[tuple[float, float], list[tuple[TrialData, int, int]]] = defaultdict(list)
    lengths = []
    for d in datas:
        for i, j in _strides(d):
            duration = float(d.columns["t"][j] - d.columns["t"][i])
            length = float(d.columns["stride_length_m"][j])
            incline = float(np.nanmean(d.columns["incline_deg"][i:j]))
            if not (math.isfinite(length) and math.isfinite(incline)):
                continue
            speed = length / duration
            lengths.append(length)
            profile.append(
                schema.StrideProfilePoint(
                    trial_id=d.trial.id,
                    t=round(float(d.columns["t"][i]), 3),
                    duration_s=round(duration, 4),
                    speed_m_s=round(speed, 4),
                    incline_deg=round(incline, 3),
                )
            )
            groups[(_bin(speed, SPEED_BIN), _bin(incline, INCLINE_BIN))].append((d, i, j))
    conditions = []
    for (speed, incline), strides in sorted(groups.items(), key=lambda kv: (kv[0][1], kv[0][0])):
        signals: dict[str, list[float | None]] = {}
        overlays: dict[str, list[list[float | None]]] = {}
        keep = np.unique(np.linspace(0, len(strides) - 1, min(len(strides), schema.SUMMARY_MAX_OVERLAY)).round())
        for signal in OVERLAY_SIGNALS:
            curves = np.array([_curve(d, signal, i, j) for d, i, j in strides])
            if not np.isfinite(curves).any():
                continue
            with np.errstate(all="ignore"):
                mean = np.nanmean(np.where(np.isfinite(curves), curves, np.nan), axis=0) if len(curves) else curves
            signals[signal] = _nullable(np.asarray(mean))
            overlays[signal] = [_nullable(curves[int(k)]) for k in keep]
        conditions.append(
            schema.StrideCondition(
                label=f"{speed:.1f} m/s, {incline:+.1f}°",
                speed_m_s=speed,
                incline_deg=incline,
                strides=len(strides),
                percent=[round(100.0 * k / (POINTS - 1), 3) for k in range(POINTS)],
                signals=signals,
                overlays=overlays,
            )
        )
    events = store.list_events(session_id)
    history = [
        schema.SettingChangeRow(t=e.t, wall_utc=e.wall_utc, text=setting_text(e)) for e in events if e.kind == "setting"
    ]
    settings_start = None
    for d in datas:
        try:
            settings_start = recorded_settings(data_dir / d.trial.path)
            break
        except ValueError:
            continue
    total_strides = len(profile)
    recorded = sum(p.duration_s for p in profile)
    summary = schema.SessionSummary(
        session_id=session.id,
        subject_id=subject.id,
        subject_code=subject.code,
        state=session.state,
        source=_SOURCES.get(session.source.kind, session.source.kind),
        started_utc=session.started_utc,
        stopped_utc=session.stopped_utc,
        duration_s=_duration(session, datas),
        trials=trials,
        strides=total_strides,
        mean_speed_m_s=round(sum(p.speed_m_s * p.duration_s for p in profile) / recorded, 4) if profile else None,
        mean_stride_length_m=round(float(np.mean(lengths)), 4) if lengths else None,
        mean_cadence_spm=round(60.0 * total_strides / recorded, 2) if profile else None,
        profile=profile,
        settings_start=settings_start,
        settings_end=session.settings,
        settings_history=history,
        conditions=conditions,
        health=_health(datas, trials),
        events=events,
    )
    return summary, datas
