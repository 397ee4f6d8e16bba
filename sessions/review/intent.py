"""Reviewing a trial's speed-change intent: its ``intent`` estimator's outputs over time, or why there are none.

A trial whose stack ran the intent estimator (seed 001; a live session's or an import's, whenever the
channels allowed) records its outputs on ``/estimators/intent``; they come back decimated as a series
(:func:`~gaitscope.sessions.formats.mcap_io.read_estimator_series`), desired and actual speed to plot. A trial that
does not record them either lacks channels the estimator requires (named, as
:func:`~gaitscope.sessions.registry.feeds` reckons them from its first frames, so that a review says which instead
of drawing an empty plot) or ran a stack without it: a re-run with it (:mod:`gaitscope.sessions.review.rerun`) then
shows it.
"""

from __future__ import annotations

from pathlib import Path

from gaitscope.sessions.formats.mcap_io import read_estimator_series
from gaitscope.sessions.live.intent_events import INTENT
from gaitscope.sessions.registry import feeds
from gaitscope.sessions.review.rerun import trial_channels
from gaitscope.sessions.schema import IntentSeries

__all__ = ["intent_series"]


def intent_series(path: Path, t0: float | None, t1: float | None, max_points: int) -> IntentSeries:
    """The trial's recorded intent outputs within session times ``[t0, t1]`` (None: unbounded), at most
    about ``max_points`` rows, or the channels the estimator lacks.

    Raises:
        DataFormatError: a bad file.
    """
    series = read_estimator_series(path, INTENT, t0, t1, max_points)
    if series is not None:
        return IntentSeries(recorded=True, series=series)
    missing = feeds(trial_channels(path))[INTENT].missing
    return IntentSeries(recorded=False, missing=list(missing))
