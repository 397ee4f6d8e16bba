"""The PDF report typesets what it is given as text: markup in a trial name or a note is printed, not run."""

from __future__ import annotations

import io

from pypdf import PdfReader

from gaitscope.sessions import schema
from gaitscope.sessions.reports.pdf import FIGURE_TITLES, render_pdf

NASTY = '#panic("boom") *bold* $x^2$ <lbl> @ref // not a comment'


def _summary() -> schema.SessionSummary:
    trial = schema.Trial(id=3, session_id=2, name=NASTY, status="finished", path="r.mcap",
                         started_utc="2026-01-02T10:00:00.123Z", duration_s=75.0)  # fmt: skip
    event = schema.Event(id=1, session_id=2, t=4.0, wall_utc="x", kind="annotation", text=NASTY, actor="dr-#k")
    return schema.SessionSummary(
        session_id=2, subject_id=1, subject_code="S_01", state="stopped", source="live device",
        started_utc="2026-01-02T10:00:00Z", stopped_utc="2026-01-02T10:01:20Z", duration_s=80.0, trials=[trial],
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
    assert "Session 2 of S_01" in text and "Duration 1 min 20 s (80.0 s)" in text
    assert text.count('#panic("boom") *bold* $x^2$ <lbl> @ref // not a comment') == 2  # the trial and the note
    assert "dr-#k" in text and "2026-01-02 10:00:00 UTC" in text
    assert "Mean speed not available" in text and "No setting was changed" in text
    assert not any(caption in text for caption in FIGURE_TITLES.values())  # no stride: no figure
