"""The PDF report typesets what it is given as text: markup in a trial name or a note is printed, not run."""

from __future__ import annotations

import io

from pypdf import PdfReader

from gaitscope.sessions import schema
from gaitscope.sessions.reports.pdf import FIGURE_TITLES, profile_line, render_pdf

NASTY = '#panic("boom") *bold* $x^2$ <lbl> @ref // not a comment'


def _summary() -> schema.SessionSummary:
    trial = schema.Trial(id=3, session_id=2, name=NASTY, status="finished", path="r.mcap",
                         started_utc="2026-01-02T10:00:00.123Z", duration_s=75.0)  # fmt: skip
    event = schema.Event(id=1, session_id=2, t=4.0, wall_utc="x", kind="annotation", text=NASTY, actor="dr-#k")
    return schema.SessionSummary(
        session_id=2, subject_id=1, subject_code="S_01", state="stopped", source="live device",
        started_utc="2026-01-02T10:00:00Z", stopped_utc="2026-01-02T10:13:20Z", duration_s=75.0, wall_s=800.0,
        trials=[trial],
        strides=0, mean_speed_m_s=None, mean_stride_length_m=None, mean_cadence_spm=None, profile=[],
        settings_start=None, settings_end=schema.SessionSettings(), settings_history=[], conditions=[],
        health=schema.DataHealthFigures(samples=0, recorded_s=0.0, rate_hz=None, gaps=0, longest_gap_s=0.0,
                                        missing_percent=0.0, faults=0, backup_resets=0, trials_recovered=0,
                                        trials_damaged=0),
        events=[event],
    )  # fmt: skip


def test_markup_is_printed_as_text_and_missing_figures_are_left_out() -> None:
    pdf = render_pdf(_summary(), version="9.9.9", generated_utc="2026-01-02 10:05 UTC")
    text = " ".join(" ".join(p.extract_text() or "" for p in PdfReader(io.BytesIO(pdf)).pages).split())
    assert "Session 2 of S_01" in text and "Duration 1 min 15 s (75.0 s) recorded in 1 trial" in text
    assert "Wall time 13 min 20 s (800.0 s) from start to stop" in text  # beside it, named apart
    assert text.count('#panic("boom") *bold* $x^2$ <lbl> @ref // not a comment') == 2  # the trial and the note
    assert "dr-#k" in text and "2026-01-02 10:00:00 UTC" in text
    assert "Mean speed not available" in text and "No setting was changed" in text
    assert not any(caption in text for caption in FIGURE_TITLES.values())  # no stride: no figure


def test_a_profile_line_breaks_at_gaps() -> None:
    """Issue #23: the speed profile does not bridge time not recorded with a straight line."""

    def point(t: float, v: float, gap: bool = False) -> schema.StrideProfilePoint:
        return schema.StrideProfilePoint(trial_id=1, t=t, duration_s=1.0, speed_m_s=v, incline_deg=0.0, after_gap=gap)

    prof = [point(0.0, 1.0, True), point(1.0, 1.1), point(60.0, 0.8, True), point(61.0, 0.9)]
    assert profile_line(prof, "speed_m_s") == ([0.0, 1.0, 60.0, 60.0, 61.0], [1.0, 1.1, None, 0.8, 0.9])


def test_a_trial_report_names_the_trial_and_the_estimator_by_its_label() -> None:
    s = _summary()
    s = s.model_copy(update={"trial_id": 3, "trials": [s.trials[0].model_copy(update={"name": "walk 2"})],
                             "settings_end": schema.SessionSettings(primary="tbe")})  # fmt: skip
    pdf = render_pdf(s, version="9.9.9", generated_utc="2026-01-02 10:05 UTC")
    text = " ".join(" ".join(p.extract_text() or "" for p in PdfReader(io.BytesIO(pdf)).pages).split())
    assert "Trial walk 2 of session 2, S_01" in text and "Torque follows Timing-based estimate" in text
    assert "tbe" not in text.replace("Timing-based estimate", "")
