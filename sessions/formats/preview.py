"""An upload's import preview: what an import would read, before anything is stored (issue #25).

:func:`preview_log` reads the first :data:`~gaitscope.sessions.schema.PREVIEW_S` seconds of an upload the way
:func:`~gaitscope.sessions.formats.imports.import_log` reads the whole of it (the same readers, the same mapping,
the same registry rule and value checks) and says: the channels found, their units and ranges against the
plausible ones, a small plot of each, the estimators the file can feed and what the others lack, what it would
ignore, and, for a file that needs a mapping (another tool's MCAP recording, a C3D file), the mapping in use and
the file's fields to edit it. A problem the import would refuse the file for is the preview's ``problem``
rather than an error, so that the person can change the mapping and look again; a file that is not a log at all
is refused as the import refuses it.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator

import numpy as np

from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.estimation import FrameEstimator
from gaitscope.sessions.formats.feeding import Plausibility, report
from gaitscope.sessions.formats.imports import (
    ImportJob,
    ImportRefused,
    Source,
    cannot_feed,
    detect_format,
    foreign,
    frames_of,
    user_errors,
)
from gaitscope.sessions.formats.mcap_io import read_messages
from gaitscope.sessions.registry import MissingChannels, channels_of

__all__ = ["MAX_PREVIEW_FRAMES", "preview_log", "run_preview"]

#: Frames a preview reads at most, whatever their rate (60 s at 1 kHz).
MAX_PREVIEW_FRAMES = 60_000


def run_preview(job: ImportJob) -> schema.ImportPreview:
    """:func:`preview_log` for a worker process: a refused file raises
    :class:`~gaitscope.sessions.formats.imports.ImportRefused`."""
    try:
        return preview_log(job)
    except DataFormatError as err:
        raise ImportRefused(str(err)) from None


def preview_log(job: ImportJob, seconds: float = schema.PREVIEW_S) -> schema.ImportPreview:
    """The preview of ``job.upload`` (module docstring); ``job.target`` is not written.

    Raises:
        DataFormatError: the file is no log gaitscope reads (its format, a damaged file).
    """
    with user_errors(job):
        fmt = detect_format(job.upload, job.filename)
        if fmt == "mcap" and not foreign(job.upload, job.filename):
            frames = (schema.SensorFrame.model_validate(m) for _, _, m in read_messages(job.upload, ["/sensor"]))
            source = Source(frames, "mcap", [])
        else:
            source = frames_of(job, fmt)
        fields = _fields(job, source)
    problem = None
    try:
        with user_errors(job):  # the problem in the user's terms, for the preview to show
            taken = _first_seconds(source.frames, seconds, job.filename)
    except DataFormatError as err:
        taken, problem = [], str(err)
    complete = problem is None and len(taken) < MAX_PREVIEW_FRAMES and _ended(source.frames)
    channels = channels_of(taken)
    checks = Plausibility(channels)
    checks.add(taken)
    ran: tuple[str, ...] = ()
    if problem is None:
        problem, ran = _stack(job, taken, channels)
    if problem is None and (refused := checks.refusal()) is not None:
        problem = f"column {refused[0]}: {refused[1]}"
    t, series = _plot(taken, channels)
    kind = None if source.mapping is None else source.mapping[1]
    return schema.ImportPreview(
        filename=job.filename,
        format=source.format,
        previewed_s=(taken[-1].t - taken[0].t) if taken else 0.0,
        complete=complete,
        report=report(source.format, channels, ran, source.ignored, checks.warnings()),
        channels=checks.summary(),
        t=t,
        series=series,
        mapping_kind=kind,
        mapping=None if source.mapping is None else source.mapping[0],
        mapping_source=None if source.mapping is None else ("given" if job.mapping else "suggested"),
        rig=None if source.mapping is None else source.mapping[2],
        fields=fields,
        problem=problem,
    )


def _first_seconds(frames: Iterator[schema.SensorFrame], seconds: float, name: str) -> list[schema.SensorFrame]:
    out: list[schema.SensorFrame] = []
    for frame in itertools.islice(frames, MAX_PREVIEW_FRAMES):
        out.append(frame)
        if frame.t - out[0].t >= seconds:
            break
    if len(out) < 2:
        raise DataFormatError("the log holds fewer than 2 sensor frames", file=name)
    return out


def _ended(frames: Iterator[schema.SensorFrame]) -> bool:
    """Whether ``frames`` has nothing left (it reads one more frame at most)."""
    try:
        next(frames)
    except (StopIteration, DataFormatError):
        return True
    return False


def _stack(job: ImportJob, taken: list[schema.SensorFrame], channels: set[str]) -> tuple[str | None, tuple[str, ...]]:
    """Why the import would refuse the frames' channels (None: it would not), and the stack it would run."""
    period = float(np.median(np.diff([f.t for f in taken])))
    try:
        est = FrameEstimator(
            job.model,
            job.subject.leg_length_m,
            job.subject.mass_kg,
            schema.SessionSettings(),
            period,
            channels=channels,
        )
    except (MissingChannels, ValueError) as err:
        return cannot_feed(channels, str(err)), ()
    return None, est.stack.names


def _plot(taken: list[schema.SensorFrame], channels: set[str]) -> tuple[list[float], dict[str, list[float | None]]]:
    """At most :data:`~gaitscope.sessions.schema.PREVIEW_POINTS` samples of every channel, evenly spread."""
    if not taken:
        return [], {}
    picks = np.unique(np.linspace(0, len(taken) - 1, min(len(taken), schema.PREVIEW_POINTS)).round().astype(int))
    rows = [taken[i] for i in picks]
    t0 = taken[0].t
    series: dict[str, list[float | None]] = {}
    for c in schema.CHANNELS:
        if c in channels:
            values = [getattr(f, c) for f in rows]
            series[c] = [None if v is None or not math.isfinite(float(v)) else float(v) for v in values]
    return [round(f.t - t0, 6) for f in rows], series


def _fields(job: ImportJob, source: Source) -> list[schema.SourceField]:
    """The file's fields a mapping can name, with the channel the mapping in use gives each."""
    if source.mapping is None:
        return []
    text, kind, _ = source.mapping
    if kind == "c3d":
        from gaitscope.sessions.formats import c3d

        mapping = c3d.C3DMapping.from_json(text, job.filename)
        summary = c3d.inspect_c3d(job.upload, job.filename, mapping)
        roles = {label: role for role, label in summary.roles_found.items()}
        marks = [
            schema.SourceField(topic="marker", path=m, kind="marker", channel=roles.get(m)) for m in summary.markers
        ]
        analog = [
            schema.SourceField(topic="analog", path=a, kind="analog", channel=mapping.analog.get(a, (None,))[0])
            for a in summary.analog
        ]
        return marks + analog
    from gaitscope.sessions.formats import foreign_mcap as fm

    entries = {(e.topic, e.field): e.channel for e in fm.ChannelMapping.from_json(text).entries}
    return [
        schema.SourceField(
            topic=f.topic,
            path=f.path,
            kind=f.kind,
            count=f.count,
            rate_hz=f.rate_hz,
            min=f.min,
            max=f.max,
            channel=entries.get((f.topic, f.path)),
        )
        for f in fm.inspect_mcap(job.upload, job.filename)
    ]
