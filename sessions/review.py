"""Reviewing a recorded trial: re-run its raw sensor frames through the estimators with other settings.

Frames are read lazily and the result is decimated on the fly (:class:`~sessions.recording.SeriesBuilder`),
so a re-run of an hour-long trial needs memory for ``max_points`` rows, not for the hour. The estimator
always starts from the trial's first frame (the filter must converge as it did live); only the states
inside ``[t0, t1]`` are returned, on the recording's session times so they overlay the original.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

from estimators.pipeline import TrainedModel
from sessions.estimation import DEFAULT_PERIOD, FrameEstimator
from sessions.mcap_io import SeriesBuilder, count_messages, iter_sensor_frames, series_window
from sessions.schema import SessionSettings


def rerun_series(
    path: Path,
    model: TrainedModel,
    leg_length: float,
    mass_kg: float,
    settings: SessionSettings,
    t0: float | None = None,
    t1: float | None = None,
    max_points: int = 2000,
) -> dict[str, list[Any]]:
    """Series (as :func:`~sessions.recording.read_series`) of the trial re-estimated with ``settings``."""
    window = series_window(path, t0, t1)
    if window is None:
        return SeriesBuilder(0, max_points).result()
    lo, hi = window
    builder = SeriesBuilder(count_messages(path, "/sensor", lo, hi), max_points)
    frames = iter_sensor_frames(path)
    head = list(itertools.islice(frames, 2))
    period = head[1][1].t - head[0][1].t if len(head) == 2 and head[1][1].t > head[0][1].t else DEFAULT_PERIOD
    estimator = FrameEstimator(model, leg_length, mass_kg, settings, period, time_origin=0.0)
    for log_time, frame in itertools.chain(head, frames):
        state = estimator.step(frame, 0)
        if (lo is None or log_time >= lo) and (hi is None or log_time <= hi):
            builder.add(state.model_dump())
    return builder.result()
