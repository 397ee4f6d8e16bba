"""A stopped session's summary (:class:`~gaitscope.sessions.schema.SessionSummary`) from its rows and recordings.

Strides run from one heel strike (``GaitState.heel_strike``) to the next. A stride's speed is the
estimated stride length at its end over its duration, its incline the mean estimated incline over it.
Strides shorter than :data:`MIN_STRIDE_S`, longer than :data:`MAX_STRIDE_S` (standing, a gap) or holding a
fault (the filters were reset, the torque forced to 0) are left out of the profile and the overlays; the
profile's line breaks where they were, and between trials (``StrideProfilePoint.after_gap``), so that it never
bridges time that was not recorded.

**Conditions.** A stride's condition is its speed rounded to :data:`SPEED_BIN` m/s and its incline rounded to
:data:`INCLINE_BIN` degrees. A condition is one the walker held: strides count towards it only in runs of at
least :data:`MIN_RUN` consecutive strides (no gap between them) of that condition, and it is listed only with at
least :data:`MIN_CONDITION_STRIDES` such strides (both 3: a short session's one condition is listed, a ramp's
strides, one or two per bin, are not). A stride that straddles a change of the protocol, or one of the
strides walked while the speed or the incline ramped, is alone in its bin, so it makes no condition (the summary
counts them as ``transition_strides``). A condition's curves are each signal resampled over the stride at
:data:`POINTS` points (0-100 %).

**Duration.** ``duration_s`` is the time recorded (the sum of the trials' recorded durations), ``wall_s`` the
session's wall time from start to stop: a session paused between trials has more of the second than the first.

Names on screen come from the one table of each: settings from ``schema.SETTING_NAMES``, estimators from their
descriptors' labels.
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
    "MIN_CONDITION_STRIDES",
    "MIN_RUN",
    "MIN_STRIDE_S",
    "OVERLAY_SIGNALS",
    "POINTS",
    "SETTING_NAMES",
    "SPEED_BIN",
    "TrialData",
    "change_text",
    "event_text",
    "history_rows",
    "read_trial",
    "session_summary",
    "setting_text",
    "with_events",
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
#: Least consecutive strides of one condition that count towards it (a run), and least strides a condition needs.
MIN_RUN: Final = 3
MIN_CONDITION_STRIDES: Final = 3
#: Fields of setting events by the name a clinician reads (``schema.SETTING_NAMES``, the one table).
SETTING_NAMES: Final = {k: name for k, (name, _) in schema.SETTING_NAMES.items()}
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


def _estimator_label(name: str) -> str:
    from gaitscope.sessions.registry import descriptors

    d = descriptors().get(name)
    return d.label if d is not None else name


def _learned_model(field: str) -> str | None:
    from gaitscope.sessions.registry import descriptors

    d = descriptors().get(field)
    return d.learned_model if d is not None else None


def change_text(event: schema.Event) -> str:
    """A setting change in words: ``"Torque gain 1.00 → 1.30"`` (numbers with two decimals, the setting's unit
    after them), ``"Torque follows Phase EKF (seed 000) → Timing-based estimate"``."""
    field = event.field or ""
    model = _learned_model(field)
    name, unit = schema.SETTING_NAMES.get(field, (model or field.replace("_", " ").capitalize() or "Setting", ""))

    def shown(v: float | str | None) -> str:
        if v is None:
            return "none"
        if field == "primary" and isinstance(v, str):
            return _estimator_label(v)
        if model is not None and isinstance(v, float | int):
            return f"v{round(v)}"
        if isinstance(v, float | int) and not isinstance(v, bool):
            return f"{v:.2f}" + (f" {unit}" if unit and unit != "×" else "")
        return str(v)

    return f"{name} {shown(event.before)} → {shown(event.after)}"


def setting_text(event: schema.Event) -> str:
    """A setting change in words with its author: ``"Torque gain 1.00 → 1.30, by clinician"`` (:func:`change_text`)."""
    return f"{change_text(event)}, by {event.actor}"


def event_text(event: schema.Event) -> str:
    """An event's text as a report shows it: a setting change in words (:func:`change_text`), never the stored
    text with machine names (``primary phase_ekf -> tbe``); any other event's own text."""
    return change_text(event) if event.kind == "setting" and event.field else event.text


def history_rows(events: list[schema.Event]) -> list[schema.SettingChangeRow]:
    """The setting changes among ``events``, in words."""
    return [
        schema.SettingChangeRow(t=e.t, wall_utc=e.wall_utc, text=setting_text(e)) for e in events if e.kind == "setting"
    ]


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


def _wall_s(started_utc: str | None, stopped_utc: str | None) -> float | None:
    """Wall time from start to stop (None until stopped)."""
    import datetime as dt

    if not (started_utc and stopped_utc):
        return None
    start = dt.datetime.fromisoformat(started_utc.replace("Z", "+00:00"))
    stop = dt.datetime.fromisoformat(stopped_utc.replace("Z", "+00:00"))
    return round((stop - start).total_seconds(), 3)


@dataclass(frozen=True)
class _Stride:
    data: TrialData
    i: int
    j: int
    key: tuple[float, float]  # (speed, incline), binned


def _held(strides: list[_Stride]) -> tuple[dict[tuple[float, float], list[_Stride]], int]:
    """The conditions the walker held (see the module docstring) and how many strides are in none. ``strides``
    in the order walked; two are consecutive when one ends at the heel strike the other starts at."""
    runs: list[list[_Stride]] = []
    for st in strides:
        last = runs[-1][-1] if runs else None
        if last is not None and last.data is st.data and last.j == st.i and last.key == st.key:
            runs[-1].append(st)
        else:
            runs.append([st])
    groups: dict[tuple[float, float], list[_Stride]] = defaultdict(list)
    for run in runs:
        if len(run) >= MIN_RUN:
            groups[run[0].key].extend(run)
    held = {k: v for k, v in groups.items() if len(v) >= MIN_CONDITION_STRIDES}
    return held, len(strides) - sum(len(v) for v in held.values())


def _condition(speed: float, incline: float, strides: list[_Stride]) -> schema.StrideCondition:
    signals: dict[str, list[float | None]] = {}
    overlays: dict[str, list[list[float | None]]] = {}
    keep = np.unique(np.linspace(0, len(strides) - 1, min(len(strides), schema.SUMMARY_MAX_OVERLAY)).round())
    for signal in OVERLAY_SIGNALS:
        curves = np.array([_curve(st.data, signal, st.i, st.j) for st in strides])
        if not np.isfinite(curves).any():
            continue
        with np.errstate(all="ignore"):
            mean = np.nanmean(np.where(np.isfinite(curves), curves, np.nan), axis=0) if len(curves) else curves
        signals[signal] = _nullable(np.asarray(mean))
        overlays[signal] = [_nullable(curves[int(k)]) for k in keep]
    return schema.StrideCondition(
        label=f"{speed:.1f} m/s, {incline:+.1f}°",
        speed_m_s=speed,
        incline_deg=incline,
        strides=len(strides),
        percent=[round(100.0 * k / (POINTS - 1), 3) for k in range(POINTS)],
        signals=signals,
        overlays=overlays,
    )


def with_events(
    summary: schema.SessionSummary, session: schema.Session, events: list[schema.Event]
) -> schema.SessionSummary:
    """A summary with the session's state, settings and events as they are now (the parts not read from the
    recordings: a kept summary is brought up to date with them without reading the recordings again)."""
    if summary.trial_id is not None:
        return summary
    return summary.model_copy(
        update={
            "state": session.state,
            "stopped_utc": session.stopped_utc,
            "wall_s": _wall_s(session.started_utc, session.stopped_utc),
            "settings_end": session.settings,
            "settings_history": history_rows(events),
            "events": events,
        }
    )


def session_summary(
    store: Store,
    data_dir: Path,
    session_id: int,
    *,
    trial_id: int | None = None,
    on_progress: Callable[[int, int], None] | None = None,
) -> tuple[schema.SessionSummary, list[TrialData]]:
    """The summary of a session (or of one trial of it: ``trial_id``) and the trial data it was made from
    (the exports reuse them).

    ``on_progress(done, total)`` is called as the recordings are read, in gait states (progress of a long
    export). Trials still recording or damaged are listed but not read.

    Raises:
        NotFound: no such session, or no such trial in it.
    """
    from gaitscope.sessions.review.rerun import recorded_settings
    from gaitscope.sessions.store import NotFound

    session = store.get_session(session_id)
    subject = store.get_subject(session.subject_id)
    trials = store.list_trials(session_id)
    if trial_id is not None:
        trials = [t for t in trials if t.id == trial_id]
        if not trials:
            raise NotFound(f"trial {trial_id} is not a trial of session {session_id}")
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
    walked: list[_Stride] = []
    lengths = []
    for d in datas:
        end = None  # the sample the last usable stride of this trial ended at
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
                    after_gap=end != i,
                )
            )
            end = j
            walked.append(_Stride(d, i, j, (_bin(speed, SPEED_BIN), _bin(incline, INCLINE_BIN))))
    held, transitions = _held(walked)
    conditions = [
        _condition(speed, incline, strides)
        for (speed, incline), strides in sorted(held.items(), key=lambda kv: (kv[0][1], kv[0][0]))
    ]
    events = store.list_events(session_id)
    if trial_id is not None:
        events = store.trial_events(trial_id)
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
        trial_id=trial_id,
        subject_id=subject.id,
        subject_code=subject.code,
        state=session.state,
        source=_SOURCES.get(session.source.kind, session.source.kind),
        started_utc=trials[0].started_utc if trial_id is not None else session.started_utc,
        stopped_utc=trials[0].stopped_utc if trial_id is not None else session.stopped_utc,
        duration_s=round(sum(t.duration_s for t in trials), 3),
        wall_s=_wall_s(trials[0].started_utc, trials[0].stopped_utc)
        if trial_id is not None
        else _wall_s(session.started_utc, session.stopped_utc),
        trials=trials,
        strides=total_strides,
        transition_strides=transitions,
        mean_speed_m_s=round(sum(p.speed_m_s * p.duration_s for p in profile) / recorded, 4) if profile else None,
        mean_stride_length_m=round(float(np.mean(lengths)), 4) if lengths else None,
        mean_cadence_spm=round(60.0 * total_strides / recorded, 2) if profile else None,
        profile=profile,
        settings_start=settings_start,
        settings_end=session.settings,
        settings_history=history_rows(events),
        conditions=conditions,
        health=_health(datas, trials),
        events=events,
    )
    return summary, datas
