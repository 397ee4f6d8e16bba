"""Stride segmentation, curves and words of :mod:`gaitscope.sessions.reports.summary`, on made-up gait states."""

from __future__ import annotations

import numpy as np

from gaitscope.sessions import schema
from gaitscope.sessions.reports import summary as sm

TRIAL = schema.Trial(id=1, session_id=1, name="t", status="finished", path="x.mcap", started_utc="2026-01-01T00:00:00Z")


def _data(strike_times: list[float], *, rate: float = 100.0, fault_at: float | None = None) -> sm.TrialData:
    t = np.arange(0.0, strike_times[-1] + 0.5, 1.0 / rate)
    strikes = np.zeros(t.size, dtype=bool)
    for ts in strike_times:
        strikes[round(ts * rate)] = True
    fault = np.zeros(t.size, dtype=bool)
    if fault_at is not None:
        fault[round(fault_at * rate)] = True
    cols = {
        "t": t,
        "stride_length_m": np.full(t.size, 1.2),
        "incline_deg": np.full(t.size, 4.9),
        "torque_Nm": np.sin(2 * np.pi * t),
        "thigh_angle_deg": 20 * np.cos(2 * np.pi * t),
        "shank_angle_deg": np.full(t.size, np.nan),
        "foot_angle_deg": np.full(t.size, np.nan),
    }
    return sm.TrialData(TRIAL, cols, {"heel_strike": strikes, "fault": fault, "backup_reset": np.zeros(t.size, bool)})


def test_strides_run_heel_strike_to_heel_strike_and_skip_odd_ones() -> None:
    d = _data([0.0, 1.0, 2.0, 2.2, 6.0, 7.0, 8.0], fault_at=7.5)
    # 2.0-2.2 too short, 2.2-6.0 too long (standing), 7.0-8.0 holds a fault
    assert sm._strides(d) == [(0, 100), (100, 200), (600, 700)]


def test_a_stride_curve_is_resampled_over_the_stride() -> None:
    d = _data([0.0, 1.0, 2.0])
    curve = sm._curve(d, "torque_Nm", 0, 100)
    assert curve.shape == (sm.POINTS,)
    np.testing.assert_allclose(curve, np.sin(2 * np.pi * np.linspace(0, 1, sm.POINTS)), atol=2e-3)
    assert np.isnan(sm._curve(d, "foot_angle_deg", 0, 100)).all()


def test_bins_and_setting_words() -> None:
    assert sm._bin(1.13, sm.SPEED_BIN) == 1.2 and sm._bin(4.9, sm.INCLINE_BIN) == 5.0 and sm._bin(-0.4, 2.5) == 0.0
    ev = schema.Event(id=1, session_id=1, t=3.0, wall_utc="x", kind="setting", text="torque_gain 1 -> 1.3",
                      field="torque_gain", before=1.0, after=1.3, actor="dr-k")  # fmt: skip
    assert sm.setting_text(ev) == "Torque gain 1.00 → 1.30, by dr-k"
    ev = ev.model_copy(update={"field": "max_torque_Nm", "before": 40.0, "after": 50.0})
    assert sm.setting_text(ev) == "Maximum torque 40.00 N·m → 50.00 N·m, by dr-k"


def test_setting_words_name_estimators_and_models_as_their_descriptors_do() -> None:
    """Issue #23: never ``phase_ekf -> tbe`` in a report: the estimators' labels, a learned model's versions."""
    from gaitscope.sessions.registry import descriptors

    ev = schema.Event(id=1, session_id=1, t=3.0, wall_utc="x", kind="setting", text="primary phase_ekf -> tbe",
                      field="primary", before="phase_ekf", after="tbe", actor="dr-k")  # fmt: skip
    labels = {n: d.label for n, d in descriptors().items()}
    assert sm.setting_text(ev) == f"Torque follows {labels['phase_ekf']} → {labels['tbe']}, by dr-k"
    assert "phase_ekf" not in sm.setting_text(ev) and "tbe" not in sm.setting_text(ev)
    learner = next(n for n, d in descriptors().items() if d.learned_model)
    ev = ev.model_copy(update={"field": learner, "before": 1.0, "after": 2.0})
    assert sm.setting_text(ev) == f"{descriptors()[learner].learned_model} v1 → v2, by dr-k"


def _walk(keys: list[tuple[float, float]], d: sm.TrialData | None = None, gap_after: int | None = None) -> list:
    """Strides one after the other (each ends where the next starts), of these conditions; a gap after one."""
    d = d or _data([0.0, 1.0])
    out, i = [], 0
    for k, key in enumerate(keys):
        out.append(sm._Stride(d, i, i + 100, key))
        i += 100 + (50 if k == gap_after else 0)
    return out


def test_a_condition_is_one_the_walker_held() -> None:
    """Issue #23: a stride straddling a protocol change, or the strides of a ramp, make no condition."""
    a, b, ramp1, ramp2, straddle = (1.2, 0.0), (0.8, 0.0), (1.0, 2.5), (1.0, 5.0), (1.2, -7.5)
    keys = [a] * 6 + [straddle] + [b] * 5 + [ramp1, ramp2, ramp1] + [b] * 2
    held, transitions = sm._held(_walk(keys))
    assert set(held) == {a, b} and len(held[a]) == 6 and len(held[b]) == 5  # the last 2 of b: a run too short
    assert transitions == len(keys) - 11
    # a run broken by a gap (time not recorded) is two runs: 2 + 4 strides, only the 4 count
    held, transitions = sm._held(_walk([a] * 6, gap_after=1))
    assert len(held[a]) == 4 and transitions == 2
    held, transitions = sm._held(_walk([a, a, b, a, a]))  # never 3 in a row: no condition
    assert held == {} and transitions == 5
    # runs of MIN_RUN in one condition add up to it
    held, _ = sm._held(_walk([a] * sm.MIN_RUN + [b] + [a] * sm.MIN_RUN))
    assert len(held[a]) == 2 * sm.MIN_RUN and b not in held


def test_health_counts_gaps_and_missing_angles() -> None:
    d = _data([0.0, 1.0, 2.0])
    cut = np.ones(d.n, dtype=bool)
    cut[50:60] = False  # a 0.11 s gap
    thigh = d.columns["thigh_angle_deg"].copy()
    thigh[10:20] = np.nan
    cols = {k: v[cut] for k, v in d.columns.items()} | {"thigh_angle_deg": thigh[cut]}
    d2 = sm.TrialData(TRIAL, cols, {k: v[cut] for k, v in d.flags.items()})
    h = sm._health([d2], [TRIAL])
    assert h.samples == d2.n and h.gaps == 1 and abs(h.longest_gap_s - 0.11) < 1e-9
    assert h.rate_hz == 100.0 and h.missing_percent == round(100 * 10 / d2.n, 2)


def test_a_reports_event_text_is_in_words_not_the_stored_text() -> None:
    ev = schema.Event(id=1, session_id=1, t=3.0, wall_utc="x", kind="setting", text="primary phase_ekf -> tbe",
                      field="primary", before="phase_ekf", after="tbe", actor="dr-k")  # fmt: skip
    assert sm.event_text(ev) == "Torque follows Phase EKF (seed 000) → Timing-based estimate"
    note = ev.model_copy(update={"kind": "annotation", "text": "strap loose", "field": None})
    assert sm.event_text(note) == "strap loose"
