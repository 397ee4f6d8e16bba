"""Import an uploaded log as a trial for review: gaitscope MCAP, the replay CSV, or a LocoHub table.

The format is decided by the file's name and its content together (:func:`detect_format`): an MCAP
file starts with the MCAP magic, a parquet file with ``PAR1``, a CSV file is UTF-8 text whose header
names the replay columns or the LocoHub ones; a name that says one thing and content that says
another is refused. Every refusal is a :class:`~gaitscope.sessions.errors.DataFormatError` that names the
user's file name, never the path the bytes were stored under.

The import streams (:func:`import_log`): frames are read, checked, estimated and written to the
recording in batches of :data:`BATCH_FRAMES`, so memory does not grow with the file (a LocoHub table
is the exception: it is read whole, as :func:`~gaitscope.sessions.formats.locohub.read_table` validates it, but its
frames are not). Raw logs (CSV, LocoHub, an MCAP without ``/gait_state``) are run through the
estimators with default settings so that every trial reviews the same way; an MCAP with gait states
is checked message by message and kept as it is. The recording is written to ``ImportJob.target``
and removed again on any failure. The server runs :func:`run_import` in a worker process and creates
the database rows itself once the recording is complete.

Times: every time in a log must be a finite number within :data:`MAX_ABS_TIME_S` of 0 and increase
strictly, and a log may span at most :data:`MAX_SPAN_S`; sensor values must be finite (values outside
:data:`~gaitscope.sessions.schema.SENSOR_LIMITS` are kept and treated as missing by the estimators, as live).
"""

from __future__ import annotations

import codecs
import collections
import contextlib
import csv
import dataclasses
import errno
import io
import itertools
import math
import os
import shutil
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final, Literal

import numpy as np
from pydantic import BaseModel, ValidationError

from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.estimation import FrameEstimator, torque_json
from gaitscope.sessions.formats.feeding import Plausibility, report
from gaitscope.sessions.formats.locohub import CHANNELS_OF, read_table
from gaitscope.sessions.formats.mcap_io import check_mcap, count_messages, metadata_of, read_messages
from gaitscope.sessions.formats.recording import ESTIMATORS_KEY, METADATA_NAME, SAMPLE_PERIOD_KEY, Recorder
from gaitscope.sessions.formats.replay_io import FLAGS, MAX_PERIOD_S, MIN_PERIOD_S, header_columns, parse_cells
from gaitscope.sessions.registry import MissingChannels, channels_of

__all__ = [
    "BATCH_FRAMES",
    "LOCOHUB_REPLAY_COLUMNS",
    "MAX_ABS_TIME_S",
    "MAX_SPAN_S",
    "ImportJob",
    "ImportRefused",
    "ImportResult",
    "LogFormat",
    "detect_format",
    "import_log",
    "run_import",
]

#: LocoHub columns a table needs to be imported; its signals (:data:`~gaitscope.sessions.formats.locohub.CHANNELS_OF`)
#: must feed an estimator of the gait phase (the registry's rule, as for every file).
LOCOHUB_REPLAY_COLUMNS: Final = (schema.SUBJECT, schema.TASK_ID, schema.TIME_S)
#: Frames read, estimated and written per batch: what an import holds in memory at once.
BATCH_FRAMES: Final = 256
#: Largest time (s, either sign) a log may hold: a device clock in Unix seconds fits; 1e300 does not.
MAX_ABS_TIME_S: Final = 1e10
#: Longest log (s, last time minus first): about 11.6 days.
MAX_SPAN_S: Final = 1e6

LogFormat = Literal["mcap", "parquet", "replay_csv", "locohub_csv", "c3d"]

_MCAP_MAGIC: Final = b"\x89MCAP0\r\n"
_PARQUET_MAGIC: Final = b"PAR1"
_BOM: Final = codecs.BOM_UTF8
_HEAD_BYTES: Final = 64 * 1024
_EXPECTED: Final = {".mcap": "mcap", ".parquet": "parquet", ".csv": "text", ".c3d": "c3d"}
_NOUN: Final = {".mcap": "an MCAP file", ".parquet": "a parquet file", ".csv": "a CSV file", ".c3d": "a C3D file"}
_CONTROL: Final = frozenset(chr(c) for c in (*range(0x09), 0x0B, 0x0C, *range(0x0E, 0x20), 0x7F))
_SENSOR_VALUES: Final = tuple(f for f in schema.SensorFrame.model_fields if f not in ("type", "seq", "t", "sent_ns"))


@dataclass(frozen=True)
class ImportJob:
    """One import, as the worker process receives it (every field pickles).

    Attributes:
        upload: the received bytes (a temporary file whose name says nothing).
        filename: the user's name for them; decides the format with the content, and is the file
            named in every error.
        target: the recording to write; must not exist. Removed again if the import fails.
        subject: whose log it is (leg length and mass for the estimators).
        model: the gait model to estimate with.
    """

    upload: Path
    filename: str
    target: Path
    subject: schema.Subject
    model: TrainedModel
    #: the channel mapping (JSON) of another tool's MCAP recording or of a C3D file; None: the suggested one
    mapping: str | None = None
    allow_other_rig: bool = False


@dataclass(frozen=True)
class ImportResult:
    """What :func:`import_log` wrote: ``samples`` gait states spanning ``duration_s`` seconds, and what it
    read (the channels, what they feed, the columns ignored, warnings)."""

    samples: int
    duration_s: float
    report: schema.ImportReport
    #: the mapping the import used (JSON, its kind, the file's rig), to be saved for the rig's next file
    mapping: tuple[str, schema.MappingKind, str] | None = None


class ImportRefused(ValueError):
    """The file was refused; ``str()`` is the reason, naming the user's file.

    :func:`run_import` raises it in place of :class:`~gaitscope.sessions.errors.DataFormatError`, whose
    keyword-only arguments do not survive the trip back from a worker process.
    """


def run_import(job: ImportJob) -> ImportResult:
    """:func:`import_log` for a worker process: a refused file raises :class:`ImportRefused`."""
    try:
        return import_log(job)
    except DataFormatError as err:
        raise ImportRefused(str(err)) from None


def import_log(job: ImportJob) -> ImportResult:
    """Check ``job.upload`` and write it as a recording to ``job.target``; nothing is left on failure.

    Raises:
        DataFormatError: the file is not an acceptable log (named by ``job.filename``).
        OSError: the recording could not be written (a full disk); ``job.target`` is removed.
        FileExistsError: ``job.target`` exists (it is left alone).
    """
    if job.target.exists():
        raise FileExistsError(errno.EEXIST, "the import's recording exists already", str(job.target))
    try:
        with user_errors(job):
            fmt = detect_format(job.upload, job.filename)
            if fmt == "mcap" and not foreign(job.upload, job.filename):
                return _import_mcap(job)
            source = frames_of(job, fmt)
            result = _record(job, source.frames, source.format, source.ignored)
            return dataclasses.replace(result, mapping=source.mapping)
    except BaseException:
        job.target.unlink(missing_ok=True)
        raise


@dataclass
class Source:
    """A file's frames as an import reads them (:func:`frames_of`): ``format`` is the report's (``foreign_mcap``
    for another tool's MCAP recording), ``ignored`` fills as the frames are read, ``mapping`` is the channel
    mapping used (JSON, kind, rig) when the file needed one."""

    frames: Iterator[schema.SensorFrame]
    format: str
    ignored: list[str]
    mapping: tuple[str, schema.MappingKind, str] | None = None


def foreign(path: Path, name: str) -> bool:
    """Whether an MCAP file is another tool's recording: it has channels, none of them gaitscope's ``/sensor``
    (a file that cannot be read as MCAP, or has no channel, is gaitscope's to refuse, with its reasons)."""
    from mcap.reader import make_reader

    try:
        with path.open("rb") as f:
            summary = make_reader(f).get_summary()
    except Exception:
        return False
    topics = [] if summary is None else [c.topic for c in summary.channels.values()]
    return bool(topics) and "/sensor" not in topics  # no channel at all: nobody's recording


def frames_of(job: ImportJob, fmt: LogFormat) -> Source:
    """The frames of a raw log (not a gaitscope recording with gait states), mapped where it needs it:
    another tool's MCAP recording by ``job.mapping`` (else the suggested mapping of its fields), a C3D file by
    its marker set (else Plug-in Gait)."""
    path, name = job.upload, job.filename
    ignored: list[str] = []
    if fmt == "replay_csv":
        return Source(_replay_frames(path, name, ignored), fmt, ignored)
    if fmt in ("locohub_csv", "parquet"):
        suffix = ".csv" if fmt == "locohub_csv" else ".parquet"
        return Source(_locohub_frames(path, name, suffix, ignored), fmt, ignored)
    if fmt == "c3d":
        from gaitscope.sessions.formats import c3d

        c3d_mapping = c3d.PLUG_IN_GAIT if job.mapping is None else c3d.C3DMapping.from_json(job.mapping, name)
        summary = c3d.inspect_c3d(path, name, c3d_mapping)
        ignored.extend(m for m in summary.markers if m not in summary.roles_found.values())
        used = (job.mapping or c3d.to_json(c3d_mapping), "c3d", c3d.rig_of(summary))
        return Source(c3d.c3d_frames(path, name, c3d_mapping), "c3d", ignored, used)  # type: ignore[arg-type]
    from gaitscope.sessions.formats import foreign_mcap as fm

    fields = fm.inspect_mcap(path, name)  # once: the suggestion and the fields left unread
    try:
        mapping = fm.suggest_mapping(fields) if job.mapping is None else fm.ChannelMapping.from_json(job.mapping)
    except fm.MappingError as e:
        raise DataFormatError(f"the channel mapping is not usable: {e}", file=name) from None
    rig = fm.rig_signature(path, name)
    mapped = {(e.topic, e.field) for e in mapping.entries}
    ignored.extend(f"{f.topic} {f.path}" for f in fields if (f.topic, f.path) not in mapped)
    if mapping.entries:
        frames = fm.foreign_frames(path, name, mapping, allow_other_rig=job.allow_other_rig)
    else:  # refused when read: a preview still lists the fields to map
        frames = _refused(
            "the recording is another tool's and none of its fields is named as a gaitscope channel: map its "
            "fields to channels in the upload's preview",
            name,
        )
    return Source(frames, "foreign_mcap", ignored, (mapping.to_json(), "mcap", rig))


def _refused(why: str, name: str) -> Iterator[schema.SensorFrame]:
    """Frames that are a refusal: :class:`DataFormatError` ``why`` when the first is read."""
    raise DataFormatError(why, file=name)
    yield  # a generator: the refusal comes when the frames are read


def detect_format(path: Path, filename: str) -> LogFormat:
    """The format of the file at ``path`` that the user calls ``filename``, by name and content.

    Raises:
        DataFormatError: an unsupported extension, an empty file, content that is not what the name
            says, or a CSV whose header names neither the replay nor the LocoHub columns.
    """
    suffix = Path(filename).suffix.lower()
    if suffix not in _EXPECTED:
        raise DataFormatError(f"unsupported file type {suffix!r} (use .mcap, .csv or .parquet)", file=filename)
    with path.open("rb") as f:
        head = f.read(_HEAD_BYTES)
    content, text = _content(head)
    if content == "empty":
        raise DataFormatError("the file is empty", file=filename)
    if content == "latin" and suffix == ".csv":
        raise DataFormatError("not a readable CSV file: the text is not UTF-8 (save it as UTF-8)", file=filename)
    if content != _EXPECTED[suffix]:
        found = {"mcap": "an MCAP file", "parquet": "a parquet file", "binary": "binary data"}.get(content)
        found = found or ("CSV text" if "," in text.partition("\n")[0] else "text")
        raise DataFormatError(f"not {_NOUN[suffix]}: the content is {found}", file=filename)
    if suffix == ".mcap":
        return "mcap"
    if suffix == ".c3d":
        return "c3d"
    if suffix == ".parquet":
        return "parquet"
    names = {h.strip() for h in next(csv.reader(io.StringIO(text)), [])}
    if names.issuperset(LOCOHUB_REPLAY_COLUMNS):
        return "locohub_csv"
    if schema.REPLAY_TIME in names and names & set(schema.CHANNELS):
        return "replay_csv"
    raise DataFormatError(
        f"the CSV header has neither {schema.REPLAY_TIME} and a column named as a gaitscope channel (foot_angle_deg, "
        "shank_angle_deg, thigh_angle_deg, knee_angle_deg, imu_shank_gyro_z_dps, ...: docs/api.md, Channels) "
        f"nor the LocoHub columns ({', '.join(LOCOHUB_REPLAY_COLUMNS)})",
        file=filename,
        row=1,
    )


# --- private helpers -----------------------------------------------------------------------------


def _content(head: bytes) -> tuple[str, str]:
    """What the first bytes of a file are: ``empty``, ``mcap``, ``parquet``, ``text`` (UTF-8, no
    control characters but tab and line ends), ``latin`` (text, not UTF-8) or ``binary``; and the text."""
    if head.startswith(_MCAP_MAGIC):
        return "mcap", ""
    if len(head) >= 512 and head[1:2] == b"P":  # a C3D header block: its parameter block number, then 0x50
        return "c3d", ""
    if head.startswith(_PARQUET_MAGIC):
        return "parquet", ""
    body = head.removeprefix(_BOM)
    try:
        text = codecs.getincrementaldecoder("utf-8")().decode(body, final=False)  # a cut last character is fine
    except UnicodeDecodeError:
        return ("binary" if any(b < 0x20 and b not in b"\t\r\n" for b in body) else "latin"), ""
    if _CONTROL.intersection(text):
        return "binary", ""
    return ("empty" if not text.strip() else "text"), text


@contextlib.contextmanager
def user_errors(job: ImportJob) -> Iterator[None]:
    """Re-raise every DataFormatError as one naming ``job.filename``, with server paths taken out."""
    try:
        yield
    except DataFormatError as err:
        where = str(DataFormatError("", file=err.file, column=err.column, row=err.row))
        message = _scrub(str(err).removeprefix(where), job)
        raise DataFormatError(message, file=job.filename, column=err.column, row=err.row) from None


def _scrub(message: str, job: ImportJob) -> str:
    """``message`` with every server path of the job replaced by the user's file name (files) or
    removed (folders), as given and as absolute paths."""
    files = {_link(job.upload, ".csv"), _link(job.upload, ".parquet"), job.upload, job.target}
    folders = {job.upload.parent, job.target.parent}
    for path in sorted({str(p) for p in files} | {os.path.abspath(p) for p in files}, key=len, reverse=True):
        message = message.replace(path, job.filename)  # longest first: a link's name holds the upload's
    for path in sorted({str(p) for p in folders} | {os.path.abspath(p) for p in folders}, key=len, reverse=True):
        if path not in (".", os.sep):  # a bare file name has no folder to remove
            message = message.replace(path, "")
    return message


def _link(path: Path, suffix: str) -> Path:
    return path.with_name(f"{path.name}.link{suffix}")


@contextlib.contextmanager
def _suffixed(path: Path, suffix: str) -> Iterator[Path]:
    """``path``, or a symbolic link to it named with ``suffix`` (the LocoHub reader goes by the suffix)."""
    if path.suffix.lower() == suffix:
        yield path
        return
    link = _link(path, suffix)
    link.unlink(missing_ok=True)
    link.symlink_to(path.resolve())
    try:
        yield link
    finally:
        link.unlink(missing_ok=True)


def _time_problem(t: float, first: float | None, previous: float | None) -> str | None:
    """Why ``t`` cannot follow ``previous`` in a log that started at ``first``; None if it can."""
    if math.isnan(t):
        return "t is NaN"
    if math.isinf(t):
        return "t is infinite"
    if abs(t) > MAX_ABS_TIME_S:
        return f"t = {t:g} s is out of range (a time must be within {MAX_ABS_TIME_S:g} s of 0)"
    if previous is not None and t <= previous:
        return f"time {'goes backwards' if t < previous else 'repeats'} ({t:g} after {previous:g})"
    if first is not None and t - first > MAX_SPAN_S:
        return f"the log spans {t - first:g} s (at most {MAX_SPAN_S:g} s)"
    return None


def _non_finite(message: BaseModel, fields: Sequence[str]) -> str | None:
    for name in fields:
        value = getattr(message, name)
        if isinstance(value, float) and not math.isfinite(value):
            return f"{name} is {'NaN' if math.isnan(value) else 'infinite'}"
    return None


def _validated(cls: type[BaseModel], data: Any, topic: str, n: int, name: str) -> Any:
    """``data`` (decoded JSON) as ``cls`` with a finite, in-range ``t`` and finite floats."""
    where = f"{topic} message {n}"
    if not isinstance(data, dict):
        raise DataFormatError(f"{where}: not a JSON object", file=name)
    t = data.get("t")
    if isinstance(t, float) and (problem := _time_problem(t, None, None)):
        raise DataFormatError(f"{where}: {problem}", file=name)
    try:
        message = cls.model_validate(data)
    except ValidationError as err:
        reasons = "; ".join(f"{'.'.join(str(p) for p in e['loc'])}: {e['msg']}" for e in err.errors())
        raise DataFormatError(f"{where}: {reasons}", file=name) from None
    fields = [f for f, info in cls.model_fields.items() if info.annotation in (float, float | None)]
    if problem := _non_finite(message, fields):
        raise DataFormatError(f"{where}: {problem}", file=name)
    return message


def _checked_times(messages: Iterator[Any], topic: str, name: str) -> Iterator[Any]:
    """``messages`` (each with ``t``) as they come, checked to increase within :data:`MAX_SPAN_S`."""
    first: float | None = None
    previous: float | None = None
    for n, message in enumerate(messages, start=1):
        if problem := _time_problem(message.t, first, previous):
            raise DataFormatError(f"{topic} message {n}: {problem}", file=name)
        first = message.t if first is None else first
        previous = message.t
        yield message


def _mcap_messages(path: Path, topic: str, cls: type[BaseModel], name: str) -> Iterator[Any]:
    raw = (_validated(cls, data, topic, n, name) for n, (_, _, data) in enumerate(read_messages(path, [topic]), 1))
    return _checked_times(raw, topic, name)


def _import_mcap(job: ImportJob) -> ImportResult:
    path, name = job.upload, job.filename
    size = path.stat().st_size
    with path.open("rb") as f:
        f.seek(max(0, size - len(_MCAP_MAGIC)))
        if size < 2 * len(_MCAP_MAGIC) or f.read() != _MCAP_MAGIC:
            raise DataFormatError(
                "the MCAP file is incomplete (it has no index at its end): it was cut short, "
                "or its recording was not finished",
                file=name,
            )
    check_mcap(path, name=name)
    frames = _mcap_messages(path, "/sensor", schema.SensorFrame, name)
    if count_messages(path, "/gait_state", None, None) == 0:
        return _record(job, frames, "mcap")
    counted = _Counted(frames)
    channels = channels_of(counted)
    if counted.n < 2:
        raise DataFormatError("the log holds fewer than 2 sensor frames", file=name)
    samples, first_t, last_t = 0, 0.0, 0.0
    for state in _mcap_messages(path, "/gait_state", schema.GaitState, name):
        first_t = state.t if samples == 0 else first_t
        samples, last_t = samples + 1, state.t
    with path.open("rb") as src, job.target.open("xb") as dst:  # kept as recorded
        shutil.copyfileobj(src, dst, 1024 * 1024)
        dst.flush()
        os.fsync(dst.fileno())
    ran = metadata_of(path, METADATA_NAME).get(ESTIMATORS_KEY, "")
    done = report("mcap", channels, [n for n in ran.split(",") if n])
    return ImportResult(samples=samples, duration_s=last_t - first_t, report=done)


class _Counted:
    """An iterator's items, counted as they are taken (:attr:`n`)."""

    def __init__(self, items: Iterator[schema.SensorFrame]):
        self._items = items
        self.n = 0

    def __iter__(self) -> Iterator[schema.SensorFrame]:
        for item in self._items:
            self.n += 1
            yield item


def _record(
    job: ImportJob, frames: Iterator[schema.SensorFrame], fmt: str, ignored: Sequence[str] = ()
) -> ImportResult:
    """Estimate ``frames`` batch by batch and write them with their states to ``job.target``; a file whose
    channels feed no estimator of the gait phase, or whose values are implausible for their channels
    (:class:`~gaitscope.sessions.formats.feeding.Plausibility`), is refused."""
    first = collections.deque(itertools.islice(frames, BATCH_FRAMES))
    if len(first) < 2:
        raise DataFormatError("the log holds fewer than 2 sensor frames", file=job.filename)
    period = float(np.median(np.diff([f.t for f in first])))
    if not MIN_PERIOD_S <= period <= MAX_PERIOD_S:
        raise DataFormatError(
            f"the median time step is {period:.3g} s; gaitscope takes sample periods from {MIN_PERIOD_S:g} s "
            f"to {MAX_PERIOD_S:g} s (10 kHz to 1 Hz): are the times in seconds?",
            file=job.filename,
        )
    settings = schema.SessionSettings()
    subject = job.subject
    channels = channels_of(first)
    # every estimator the log's channels allow (those of its first batch of frames)
    try:
        estimator = FrameEstimator(
            job.model, subject.leg_length_m, subject.mass_kg, settings, period, channels=channels
        )
    except (MissingChannels, ValueError) as err:  # no estimator, or none of the gait phase
        raise DataFormatError(cannot_feed(channels, str(err)), file=job.filename) from None
    checks = Plausibility(channels)
    metadata = {
        "subject": subject.code,
        "source": f"upload {job.filename}",
        SAMPLE_PERIOD_KEY: repr(estimator.sample_period),  # a review re-run reproduces the states
        ESTIMATORS_KEY: ",".join(estimator.stack.names),
    }
    with Recorder(
        job.target,
        time.time_ns(),
        metadata,
        flush_interval_s=math.inf,
        fsync_interval_s=math.inf,
        channels=estimator.recorded_channels(),
    ) as rec:
        rec.write("/settings", 0.0, settings)
        for frame in itertools.chain(_drain(first), frames):
            checks.add((frame,))
            if not estimator.accepts(frame):
                continue
            state = estimator.step(frame, 0)
            estimator.notes.clear()  # resynchronisations and filter restarts: live events, not kept here
            command = torque_json(state.seq, state.t, state.torque_Nm).encode()
            rec.write_json(state.t, estimator.recorded_json(frame, state, command))
            estimator.events.clear()  # estimator failures: their outputs say so (failed), no session to tell
    refused = checks.refusal()
    if refused is not None:
        raise DataFormatError(refused[1], file=job.filename, column=refused[0])
    done = report(fmt, channels, estimator.stack.names, ignored, checks.warnings())
    return ImportResult(samples=rec.samples, duration_s=rec.duration_s, report=done)


def cannot_feed(channels: set[str], why: str) -> str:
    """Why a log's ``channels`` cannot be estimated: what each estimator of the gait phase lacks."""
    from gaitscope.sessions.registry import DECLARED, feeds

    phased = [n for n, d in DECLARED.items() if d.phased]
    fed = feeds(channels)
    lacking = "; ".join(f"{n} needs {', '.join(fed[n].missing)}" for n in phased if fed[n].missing)
    sent = ", ".join(sorted(channels)) or "none"
    return f"the file's channels ({sent}) feed no estimator of the gait phase ({why}): {lacking}"


def _drain(items: collections.deque[schema.SensorFrame]) -> Iterator[schema.SensorFrame]:
    """The items, each let go of as it is taken."""
    while items:
        yield items.popleft()


def _replay_frames(path: Path, name: str, ignored: list[str]) -> Iterator[schema.SensorFrame]:
    """The frames of a replay CSV, read and checked a batch of rows at a time (rules of
    :func:`~gaitscope.sessions.formats.replay_io.read_replay_csv`; the first bad row of the file is reported);
    the header's columns that are not channels are appended to ``ignored``."""
    with path.open(newline="", encoding="utf-8-sig") as file:
        reader = csv.reader(file)
        try:
            header = [h.strip() for h in next(reader, [])]
            used = _replay_columns(header, name, ignored)
            batch = _ReplayBatch(name, used)
            rows: list[list[str]] = []
            lines: list[int] = []
            for row in reader:
                if not row:
                    continue
                if len(row) != len(header):
                    yield from batch.frames(rows, lines)  # a bad cell on an earlier line is reported first
                    raise DataFormatError(
                        f"expected {len(header)} fields, found {len(row)}", file=name, row=reader.line_num
                    )
                rows.append(row)
                lines.append(reader.line_num)
                if len(rows) == BATCH_FRAMES:
                    yield from batch.frames(rows, lines)
                    rows, lines = [], []
            yield from batch.frames(rows, lines)
        except (UnicodeDecodeError, csv.Error) as err:
            raise DataFormatError(f"not a readable CSV file ({err})", file=name) from None
    if batch.seq < 2:
        raise DataFormatError(f"need at least 2 data rows, found {batch.seq}", file=name)


def _replay_columns(header: list[str], name: str, ignored: list[str]) -> dict[str, int]:
    """Position of each used replay column (time first); the header checks of the replay CSV (which
    estimators the channels feed is checked on the frames)."""
    if not any(header):
        raise DataFormatError("the header row is empty", file=name, row=1)
    where, used, not_read = header_columns(header, name)
    ignored.extend(not_read)
    return {c: where[c] for c in used}


class _ReplayBatch:
    """Parses batches of replay-CSV rows into frames, carrying time and ``seq`` across batches."""

    def __init__(self, name: str, used: dict[str, int]):
        self.name = name
        self.used = used
        self.seq = 0
        self._first: float | None = None
        self._previous: float | None = None

    def frames(self, rows: list[list[str]], lines: list[int]) -> Iterator[schema.SensorFrame]:
        values: dict[str, np.ndarray] = {}
        problems: list[tuple[int, int, str, str]] = []  # (row index, column position, column, message)
        for column, j in self.used.items():
            values[column], problem = parse_cells([row[j] for row in rows], column in FLAGS)
            if problem is not None:
                problems.append((problem[0], j, column, problem[1]))
        if problems:
            i, _, column, message = min(problems)
            raise DataFormatError(message, file=self.name, column=column, row=lines[i])
        signals = [c for c in values if c not in (schema.REPLAY_TIME, schema.REPLAY_HEEL_STRIKE)]
        heel = values.get(schema.REPLAY_HEEL_STRIKE)
        for i, t in enumerate(values[schema.REPLAY_TIME].tolist()):
            if late := _time_problem(t, self._first, self._previous):
                raise DataFormatError(late, file=self.name, column=schema.REPLAY_TIME, row=lines[i])
            self._first = t if self._first is None else self._first
            self._previous = t
            fields: dict[str, Any] = {c: bool(values[c][i]) if c in FLAGS else float(values[c][i]) for c in signals}
            yield schema.SensorFrame(seq=self.seq, t=t, heel_strike=None if heel is None else bool(heel[i]), **fields)
            self.seq += 1


def _locohub_frames(path: Path, name: str, suffix: str, ignored: list[str]) -> Iterator[schema.SensorFrame]:
    """The frames of a LocoHub table: each (subject, task) in time order, repeated times dropped,
    one after the other with one median sample period between them; every signal a channel carries
    (:data:`~gaitscope.sessions.formats.locohub.CHANNELS_OF`), the others appended to ``ignored``."""
    with _suffixed(path, suffix) as readable:
        table = read_table(readable, required=LOCOHUB_REPLAY_COLUMNS)
    carried = [c for c in CHANNELS_OF if c in table.columns]
    meta = {*schema.METADATA_COLUMNS, schema.TIME_S}
    ignored.extend(c for c in table.columns if c not in meta and c not in CHANNELS_OF)
    first_row = 2 if suffix == ".csv" else 1
    offset, seq = 0.0, 0
    for _, g in table.groupby([schema.SUBJECT, schema.TASK_ID], sort=False):
        g = g.sort_values(schema.TIME_S, kind="stable")
        t = g[schema.TIME_S].to_numpy(np.float64)
        keep = np.concatenate([[True], np.diff(t) > 0])
        g, t = g[keep], t[keep]
        far = np.abs(t) > MAX_ABS_TIME_S
        if far.any():
            i = int(np.argmax(far))
            problem = f"t = {t[i]:g} s is out of range (a time must be within {MAX_ABS_TIME_S:g} s of 0)"
            raise DataFormatError(problem, file=name, column=schema.TIME_S, row=int(g.index[i]) + first_row)
        session_t = t - t[0] + offset
        if session_t[-1] > MAX_SPAN_S:
            raise DataFormatError(f"the log spans {session_t[-1]:g} s (at most {MAX_SPAN_S:g} s)", file=name)
        columns = {CHANNELS_OF[c][0]: g[c].to_numpy(np.float64) * CHANNELS_OF[c][1] for c in carried}
        heel = g[schema.HEEL_STRIKE].to_numpy(np.float64) > 0.5 if schema.HEEL_STRIKE in g.columns else None
        for k in range(len(t)):
            fields: dict[str, Any] = {c: float(v[k]) for c, v in columns.items() if math.isfinite(v[k])}
            hs = None if heel is None else bool(heel[k])
            yield schema.SensorFrame(seq=seq, t=float(session_t[k]), heel_strike=hs, **fields)
            seq += 1
        offset = float(session_t[-1]) + (float(np.median(np.diff(t))) if len(t) > 1 else 0.01)
    if seq == 0:
        raise DataFormatError("the table has no rows", file=name)
