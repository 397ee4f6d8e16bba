"""MCAP recordings made by other tools: their numeric fields, a mapping of fields to gaitscope channels, and the
mapped file streamed as :class:`~gaitscope.sessions.schema.SensorFrame` s (issue #25).

gaitscope's own recordings (:mod:`~gaitscope.sessions.formats.recording`) carry ``/sensor`` frames; another tool's
carry JSON, Protobuf or ROS 2 (CDR, ``ros2msg`` schemas) messages on topics of its own. They are decoded by the
mcap project's decoders (``mcap-protobuf-support``, ``mcap-ros2-support``; JSON by :func:`json.loads`) through
:func:`mcap.reader.make_reader`. Other encodings (ROS 1, FlatBuffers, CBOR, ROS 2 IDL schemas) are not decoded:
:func:`undecodable_topics` names them and :func:`inspect_mcap` leaves them out.

Field paths. A message's leaves are named by their path from the message root: ``angular_velocity.z``,
``position[2]`` for an array element; when a message has a ``name`` (or ``joint_names``) list of distinct strings,
its sibling arrays of the same length are indexed by those names instead: ``position[knee]`` in a ROS
``sensor_msgs/JointState``. Arrays are expanded up to ``max_array`` elements; byte arrays (images, blobs) and
text are never fields. A "field" of a mapping is this path; a topic and a path name one series.

Time. Times are integer nanoseconds. Each topic's messages are timed by their log time, or, with
``time_source="header"``, by the stamp they carry when their first message has a non-zero one (ROS
``header.stamp.sec/nanosec``, Foxglove ``timestamp.sec/nsec`` in JSON and ``timestamp.seconds/nanos`` in
Protobuf; see :data:`STAMP_FIELDS`); a topic without a stamp keeps its log time. Log time is the default
because every MCAP message has one and the file is ordered by it; header stamps are the acquisition time
(closer to the truth when a driver delivers late) but must all be on one clock with the log times they mix
with. Stamp fields are time, not data: they are not listed as fields.

A file must be finished (indexed); :func:`~gaitscope.sessions.formats.mcap_io.recover` indexes one a crash left
unfinished. Problems with a file raise :class:`~gaitscope.sessions.errors.DataFormatError` naming the file and,
as its ``column``, the topic and field; problems with a mapping itself raise :class:`MappingError`.
"""

from __future__ import annotations

import difflib
import hashlib
import heapq
import io
import itertools
import json
import math
import re
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import IO, Any, Final, Literal, get_args

from google.protobuf.message import Message as ProtoMessage
from mcap.decoder import DecoderFactory
from mcap.reader import McapReader, make_reader
from mcap.records import Channel, Schema
from mcap.summary import Summary
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory
from mcap_ros2.decoder import DecoderFactory as Ros2DecoderFactory

from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError

__all__ = [
    "MAX_ARRAY",
    "RAD_TO_DEG",
    "REORDER_S",
    "SAMPLE_MESSAGES",
    "STALE_S",
    "STAMP_FIELDS",
    "ChannelMapping",
    "FieldInfo",
    "MappingEntry",
    "MappingError",
    "RigMismatch",
    "TimeSource",
    "foreign_frames",
    "inspect_mcap",
    "rig_signature",
    "suggest_mapping",
    "undecodable_topics",
]

TimeSource = Literal["log_time", "header"]
#: Degrees per radian (180/pi): the ``scale`` of a radian field (rad, rad/s) mapped to a degree channel.
RAD_TO_DEG: Final = 57.29577951308232
#: Messages read per topic by :func:`inspect_mcap` (its ``sample_messages``).
SAMPLE_MESSAGES: Final = 200
#: Array elements expanded into fields (``max_array``): a point cloud must not become thousands of fields.
MAX_ARRAY: Final = 64
#: A channel's value older than this (s) at an output frame is absent (None) there (``stale_s``).
STALE_S: Final = 0.1
#: With header stamps, how far (s) a message may be stamped before one logged ahead of it (``reorder_s``).
REORDER_S: Final = 0.5
#: (seconds, nanoseconds) field pairs read as a message's stamp, tried in this order.
STAMP_FIELDS: Final = (
    ("header.stamp.sec", "header.stamp.nanosec"),  # ROS 2
    ("header.stamp.secs", "header.stamp.nsecs"),  # ROS 1 conventions, as JSON
    ("timestamp.sec", "timestamp.nsec"),  # Foxglove JSON schemas
    ("timestamp.seconds", "timestamp.nanos"),  # Foxglove Protobuf schemas (google.protobuf.Timestamp)
)
_STAMP_LEAVES: Final = frozenset(itertools.chain.from_iterable(STAMP_FIELDS))
_NAME_LISTS: Final = ("name", "joint_names")
_MAPPING_VERSION: Final = 1
_PROBE: Final = 50  # messages per mapped topic read to check the mapping and find the fastest topic
_NS: Final = 1_000_000_000
_MAGIC: Final = b"\x89MCAP0\r\n"
_NOT_FINISHED: Final = "the file was not finished (no index); gaitscope can recover it"
Leaf = bool | int | float | str


class MappingError(ValueError):
    """A channel mapping is invalid in itself (unknown channel, channel mapped twice, bad JSON)."""


class RigMismatch(DataFormatError):
    """The mapping was made for files from another rig (other topics or message types); see :func:`foreign_frames`."""


@dataclass(frozen=True)
class FieldInfo:
    """One numeric or boolean field of one topic, as :func:`inspect_mcap` found it.

    Attributes:
        topic, path: the series (``/imu/shank``, ``angular_velocity.z``); see the module docstring for paths.
        kind: ``number`` or ``bool``.
        message_encoding, schema_name: the topic's (``cdr``, ``sensor_msgs/msg/Imu``).
        count: messages on the topic in the whole file (the file's statistics; None without them).
        sampled: messages of the topic read (at most ``sample_messages``, the first ones in log time).
        present: of those, how many held this field as a number or flag.
        rate_hz: the topic's message rate over the sampled messages, by its time source (None below 2).
        min, max: over the sampled values (flags as 0 and 1; NaN and infinities left out; None if none).
        time_source: what times the topic's messages (``header`` only when asked for and stamped).
        rig: :func:`rig_signature` of the file.
    """

    topic: str
    path: str
    kind: Literal["number", "bool"]
    message_encoding: str
    schema_name: str
    count: int | None
    sampled: int
    present: int
    rate_hz: float | None
    min: float | None
    max: float | None
    time_source: TimeSource
    rig: str


@dataclass(frozen=True)
class MappingEntry:
    """One field to one channel: ``channel = value * scale + offset`` (flags: ``bool(value)``, no scale)."""

    topic: str
    field: str
    channel: str
    scale: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class ChannelMapping:
    """Which field of which topic feeds each gaitscope channel, for the files of one rig.

    Attributes:
        entries: one per mapped channel (a key of :data:`~gaitscope.sessions.schema.CHANNELS`); a list is
            taken and kept as a tuple.
        rig: :func:`rig_signature` of the files it was made for; ``""`` matches any file.
        time_source: how :func:`foreign_frames` times the messages (module docstring).

    Raises:
        MappingError: unknown channel names (the message lists close matches), a channel mapped twice, a
            scale of 0 or a non-finite scale or offset, a scale or offset on a flag channel, an unknown
            ``time_source``.
    """

    entries: Sequence[MappingEntry]  # kept as a tuple (the mapping is hashable)
    rig: str
    time_source: TimeSource = "log_time"

    def __post_init__(self) -> None:
        object.__setattr__(self, "entries", tuple(self.entries))
        if not all(isinstance(e, MappingEntry) and e.topic and e.field for e in self.entries):
            raise MappingError("every entry must be a MappingEntry with a topic and a field")
        unknown = [e.channel for e in self.entries if e.channel not in schema.CHANNELS]
        if unknown:
            raise MappingError(f"unknown gaitscope channels: {'; '.join(_with_matches(u) for u in unknown)}")
        targets = [e.channel for e in self.entries]
        twice = sorted({c for c in targets if targets.count(c) > 1})
        if twice:
            raise MappingError(f"channels mapped from more than one field: {', '.join(map(repr, twice))}")
        for e in self.entries:
            if not (math.isfinite(e.scale) and math.isfinite(e.offset) and e.scale != 0):
                raise MappingError(f"{e.channel}: scale must be finite and not 0, offset finite")
            if _is_flag(e.channel) and (e.scale, e.offset) != (1.0, 0.0):
                raise MappingError(f"{e.channel} is a flag: it takes no scale or offset")
        if self.time_source not in get_args(TimeSource):
            raise MappingError(f"time_source must be one of {get_args(TimeSource)}, got {self.time_source!r}")

    def to_json(self) -> str:
        """The mapping as JSON text: ``{"version": 1, "rig", "time_source", "entries": [{"topic", "field",
        "channel", "scale", "offset"}]}``."""
        body = {"version": _MAPPING_VERSION, "rig": self.rig, "time_source": self.time_source}
        return json.dumps({**body, "entries": [asdict(e) for e in self.entries]}, indent=2)

    @classmethod
    def from_json(cls, text: str | bytes) -> ChannelMapping:
        """The mapping :meth:`to_json` wrote.

        Raises:
            MappingError: not JSON, a missing, unknown or mistyped key, another version, or an invalid mapping.
        """
        try:
            data = json.loads(text)
        except ValueError as exc:
            raise MappingError(f"a channel mapping must be JSON: {exc}") from None
        _check_keys(data, {"version": int, "rig": str, "time_source": str, "entries": list}, "the mapping")
        if data["version"] != _MAPPING_VERSION:
            raise MappingError(f"mapping version {data['version']} is not {_MAPPING_VERSION}")
        entries = []
        for i, item in enumerate(data["entries"], 1):
            _check_keys(
                item, {"topic": str, "field": str, "channel": str, "scale": float, "offset": float}, f"entry {i}"
            )
            entries.append(
                MappingEntry(item["topic"], item["field"], item["channel"], float(item["scale"]), float(item["offset"]))
            )
        return cls(tuple(entries), data["rig"], data["time_source"])


def _check_keys(data: object, types: Mapping[str, type], what: str) -> None:
    if not isinstance(data, dict):
        raise MappingError(f"{what} must be a JSON object")
    missing, extra = sorted(types.keys() - data.keys()), sorted(data.keys() - types.keys())
    if missing or extra:
        raise MappingError(f"{what}: missing keys {missing}, unknown keys {extra}")
    for key, kind in types.items():
        ok = isinstance(data[key], int | float) if kind is float else isinstance(data[key], kind)
        if not ok or (kind is not bool and isinstance(data[key], bool)):
            raise MappingError(f"{what}: {key!r} must be a JSON {kind.__name__}, got {data[key]!r}")


def _with_matches(name: str) -> str:
    close = difflib.get_close_matches(name, list(schema.CHANNELS), n=3, cutoff=0.6)
    return f"{name!r} (did you mean {', '.join(map(repr, close))}?)" if close else f"{name!r} (no close match)"


def _is_flag(channel: str) -> bool:
    return schema.CHANNELS[channel].unit == "bool"


# ---------------------------------------------------------------------------------------------------------------
# Reading: the summary, decoders, flattening a decoded message into leaves, timing
# ---------------------------------------------------------------------------------------------------------------


class _JsonDecoderFactory(DecoderFactory):
    """JSON messages (any schema, or none) decoded by :func:`json.loads`."""

    def decoder_for(self, message_encoding: str, schema: Schema | None) -> Any:
        return json.loads if message_encoding == "json" else None


def _factories() -> list[DecoderFactory]:
    """Fresh decoder factories (they cache per schema id, so one set per reader)."""
    return [_JsonDecoderFactory(), ProtobufDecoderFactory(), Ros2DecoderFactory()]


def _open(f: IO[bytes], name: str) -> tuple[McapReader, Summary]:
    if f.read(len(_MAGIC)) != _MAGIC:
        raise DataFormatError("not an MCAP file (bad magic)", file=name)
    size = f.seek(0, io.SEEK_END)
    f.seek(max(0, size - len(_MAGIC)))
    if f.read(len(_MAGIC)) != _MAGIC or size < 2 * len(_MAGIC):  # no closing magic: cut short
        raise DataFormatError(_NOT_FINISHED, file=name)
    f.seek(0)
    reader = make_reader(f, decoder_factories=_factories())
    try:
        summary = reader.get_summary()
    except Exception as exc:  # the mcap library raises several types on damaged bytes
        raise DataFormatError(f"the file's index cannot be read ({exc})", file=name) from exc
    if summary is None:
        raise DataFormatError(_NOT_FINISHED, file=name)
    return reader, summary


def _schema_of(summary: Summary, channel: Channel) -> Schema | None:
    return summary.schemas.get(channel.schema_id)


def _rig(summary: Summary) -> str:
    pairs = sorted({(c.topic, s.name if (s := _schema_of(summary, c)) else "") for c in summary.channels.values()})
    return hashlib.sha256(json.dumps(pairs).encode()).hexdigest()[:16]


def _why_undecodable(summary: Summary, channel: Channel) -> str | None:
    """None when a decoder takes the channel's messages, else why not."""
    what = f"{channel.message_encoding!r} messages"
    try:
        if any(f.decoder_for(channel.message_encoding, _schema_of(summary, channel)) for f in _factories()):
            return None
    except Exception as exc:  # a schema the decoder cannot parse
        return f"{what} whose schema cannot be read ({exc})"
    return f"{what}, which gaitscope cannot decode (it reads json, protobuf and cdr with ros2msg schemas)"


def _topics(summary: Summary) -> dict[str, list[Channel]]:
    out: dict[str, list[Channel]] = {}
    for c in summary.channels.values():
        out.setdefault(c.topic, []).append(c)
    return dict(sorted(out.items()))


def _count(summary: Summary, channels: Sequence[Channel]) -> int | None:
    if summary.statistics is None:
        return None
    return sum(summary.statistics.channel_message_counts.get(c.id, 0) for c in channels)


def _flatten(
    value: Any, max_array: int, wanted: frozenset[str] | None = None, path: str = "", out: dict[str, Leaf] | None = None
) -> dict[str, Leaf]:
    """Every leaf (number, flag, text) of a decoded JSON, Protobuf or ROS 2 message by its path; with ``wanted``
    (:func:`_prefixes` of some paths), only the leaves on the way to those (a stream skips the rest)."""
    out = {} if out is None else out
    if isinstance(value, bool | int | float | str):
        out[path] = value
    elif isinstance(value, ProtoMessage):
        items = [(fd.name, getattr(value, fd.name)) for fd in value.DESCRIPTOR.fields]
        _flatten_fields(items, max_array, wanted, path, out)
    elif isinstance(value, Mapping):  # JSON objects, Protobuf maps
        _flatten_fields([(str(k), v) for k, v in value.items()], max_array, wanted, path, out)
    elif isinstance(value, SimpleNamespace):  # mcap_ros2's messages: SimpleNamespace classes with __slots__
        _flatten_fields([(n, getattr(value, n, None)) for n in value.__slots__], max_array, wanted, path, out)
    elif isinstance(value, Sequence) and not isinstance(value, bytes | bytearray):
        for i, item in enumerate(itertools.islice(value, max_array)):
            if wanted is None or f"{path}[{i}]" in wanted:
                _flatten(item, max_array, wanted, f"{path}[{i}]", out)
    return out  # None (JSON null), bytes: no leaf


def _flatten_fields(
    items: list[tuple[str, Any]], max_array: int, wanted: frozenset[str] | None, path: str, out: dict[str, Leaf]
) -> None:
    names: list[str] | None = None
    for key, v in items:
        if key in _NAME_LISTS and isinstance(v, Sequence) and not isinstance(v, str) and v:
            if all(isinstance(n, str) and n for n in v) and len(set(v)) == len(v):
                names = list(v)
    for key, v in items:
        p = f"{path}.{key}" if path else key
        if wanted is not None and p not in wanted:
            continue
        if names is not None and key not in _NAME_LISTS and isinstance(v, Sequence) and len(v) == len(names):
            if not isinstance(v, str | bytes | bytearray):
                for n, item in zip(names[:max_array], v, strict=False):
                    if wanted is None or f"{p}[{n}]" in wanted:
                        _flatten(item, max_array, wanted, f"{p}[{n}]", out)
                continue
        _flatten(v, max_array, wanted, p, out)


def _prefixes(paths: Iterable[str]) -> frozenset[str]:
    """Every path and each of its parents (cut before each ``.`` and ``[``): what :func:`_flatten` descends into."""
    return frozenset(itertools.chain.from_iterable([p[:i] for i, c in enumerate(p) if c in ".["] + [p] for p in paths))


def _stamp_ns(leaves: Mapping[str, Leaf]) -> int | None:
    for sec, nsec in STAMP_FIELDS:
        s, n = leaves.get(sec), leaves.get(nsec)
        if type(s) is int and type(n) is int:
            return s * _NS + n
    return None


class _Clock:
    """Times one topic's messages (module docstring): its first message decides log time or stamp."""

    def __init__(self, time_source: TimeSource):
        self.source: TimeSource | None = None if time_source == "header" else "log_time"

    def __call__(self, log_time: int, leaves: Mapping[str, Leaf]) -> int:
        stamp = _stamp_ns(leaves) if self.source != "log_time" else None
        if self.source is None:
            self.source = "header" if stamp else "log_time"
        return stamp if self.source == "header" and stamp is not None else log_time


def _sample(reader: McapReader, topic: str, limit: int) -> Iterator[tuple[int, Any]]:
    """(log time, decoded message) of the first ``limit`` messages of ``topic``."""
    messages = reader.iter_decoded_messages(topics=[topic], log_time_order=True)
    for _, _, message, decoded in itertools.islice(messages, limit):
        yield message.log_time, decoded


def _rate(times: Sequence[int]) -> float | None:
    span = max(times) - min(times) if len(times) > 1 else 0
    return (len(times) - 1) * _NS / span if span > 0 else None


# ---------------------------------------------------------------------------------------------------------------
# Inspection and suggestion
# ---------------------------------------------------------------------------------------------------------------


def rig_signature(path: str | Path, name: str | None = None) -> str:
    """The file's rig: a hash (16 hex digits) of its sorted distinct (topic, schema name) pairs, the same for
    every file a rig records whatever their length, so a saved :class:`ChannelMapping` can be found for it."""
    with open(path, "rb") as f:
        return _rig(_open(f, str(path) if name is None else name)[1])


def undecodable_topics(path: str | Path, name: str | None = None) -> dict[str, str]:
    """The topics whose messages gaitscope cannot decode, each with why (from the file's index only)."""
    with open(path, "rb") as f:
        _, summary = _open(f, str(path) if name is None else name)
    out: dict[str, str] = {}
    for topic, channels in _topics(summary).items():
        for c in channels:
            if (why := _why_undecodable(summary, c)) is not None:
                out[topic] = why
    return out


def inspect_mcap(
    path: str | Path,
    name: str | None = None,
    *,
    sample_messages: int = SAMPLE_MESSAGES,
    time_source: TimeSource = "log_time",
    max_array: int = MAX_ARRAY,
) -> list[FieldInfo]:
    """Every numeric and boolean field of every decodable topic, topics sorted, fields in message order.

    Reads at most ``sample_messages`` messages per topic (the first, in log time, through the index), so the
    cost is bounded whatever the file's length; ``count`` is still the whole file's. ``name`` is the file named
    in errors (an upload's own name rather than its temporary path).

    Raises:
        DataFormatError: not MCAP, not finished (no index), or a message that cannot be decoded.
        ValueError: ``sample_messages`` below 1.
    """
    if sample_messages < 1:
        raise ValueError(f"sample_messages must be at least 1, got {sample_messages}")
    name = str(path) if name is None else name
    fields: list[FieldInfo] = []
    with open(path, "rb") as f:
        reader, summary = _open(f, name)
        rig = _rig(summary)
        for topic, channels in _topics(summary).items():
            if any(_why_undecodable(summary, c) for c in channels):
                continue
            first = _schema_of(summary, channels[0])
            clock, times = _Clock(time_source), []
            seen: dict[str, list[Any]] = {}  # path -> [kind, present, min, max]
            for log_time, decoded in _decode_errors(_sample(reader, topic, sample_messages), name, topic):
                leaves = _flatten(decoded, max_array)
                times.append(clock(log_time, leaves))
                for p, v in leaves.items():
                    if isinstance(v, str) or p in _STAMP_LEAVES:
                        continue
                    row = seen.setdefault(p, ["bool" if isinstance(v, bool) else "number", 0, None, None])
                    row[1] += 1
                    if math.isfinite(x := float(v)):
                        row[2] = x if row[2] is None else min(row[2], x)
                        row[3] = x if row[3] is None else max(row[3], x)
            for p, (kind, present, lo, hi) in seen.items():
                fields.append(
                    FieldInfo(
                        topic, p, kind, channels[0].message_encoding, first.name if first else "",
                        _count(summary, channels), len(times), present, _rate(times), lo, hi,
                        clock.source or "log_time", rig,
                    )
                )  # fmt: skip
    return fields


def _decode_errors(items: Iterable[Any], name: str, topic: str | None) -> Iterator[Any]:
    """``items``, a decoding failure raised as a DataFormatError naming the topic."""
    iterator = iter(items)
    while True:
        try:
            item = next(iterator)
        except StopIteration:
            return
        except Exception as exc:  # what the decoders raise on bad bytes varies
            raise DataFormatError(f"a message could not be decoded ({exc})", file=name, column=topic) from exc
        yield item


_JOINT_STATES: Final = ("sensor_msgs/msg/JointState", "sensor_msgs/JointState")
_JOINTS: Final = ("hip", "knee", "ankle")
_NOT_ANGLE: Final = frozenset({"vel", "velocity", "speed", "torque", "effort", "moment", "force", "current", "power"})
_SEGMENTS: Final = ("pelvis", "thigh", "shank", "foot")
_IMU_FIELD: Final = re.compile(r"(?:^|\.)(angular_velocity|linear_acceleration)\.([xyz])$")


def _tokens(text: str) -> list[str]:
    return [t for t in re.split(r"[^a-z0-9]+", text.lower()) if t]


def _suggest_one(f: FieldInfo) -> tuple[int, str, float] | None:
    """(rank, channel, scale) for one field, or None; the rules are :func:`suggest_mapping`'s."""
    last = re.sub(r"\[[^\]]*\]$", "", f.path).rsplit(".", 1)[-1]
    if last in schema.CHANNELS and (f.kind == "bool") == _is_flag(last):
        return (0 if f.schema_name == "gaitscope.SensorFrame" else 1), last, 1.0
    words, topic_words = _tokens(f.path), _tokens(f.topic)
    side = "_contra" if "contra" in words + topic_words else ""
    if f.kind == "bool":
        if ("heel" in words and "strike" in words) or "heelstrike" in words:
            return 2, "heel_strike", 1.0
        return (2, f"foot_contact{side}", 1.0) if "contact" in words else None
    joint_state = f.schema_name in _JOINT_STATES
    joints = [j for j in _JOINTS if j in words]
    if joints and not _NOT_ANGLE & set(words) and (not joint_state or f.path.startswith("position[")):
        radians = joint_state or "rad" in words
        return 2, f"{joints[0]}_angle{side}_deg", RAD_TO_DEG if radians else 1.0
    if (m := _IMU_FIELD.search(f.path)) and (segments := [s for s in _SEGMENTS if s in topic_words]):
        segment = segments[0] + (side if segments[0] != "pelvis" else "")
        if m.group(1) == "angular_velocity":
            return 2, f"imu_{segment}_gyro_{m.group(2)}_dps", RAD_TO_DEG
        return 2, f"imu_{segment}_accel_{m.group(2)}_m_s2", 1.0
    return None


def suggest_mapping(fields: Sequence[FieldInfo]) -> ChannelMapping:
    """A best-effort mapping from field names, for a person to check (IMU axes and signs above all).

    What it recognises ("words" are a path's or topic's parts split at anything but letters and digits):

    1. A field whose last name is a gaitscope channel name, of the channel's kind: that channel, unscaled
       (gaitscope's own ``/sensor`` frames). These win over the rules below, and a ``gaitscope.SensorFrame``
       topic's over other topics' (a recording's ``/gait_state`` also has a ``heel_strike``).
    2. A flag with the words ``heel`` and ``strike`` (or ``heelstrike``): ``heel_strike``; a flag with the word
       ``contact``: ``foot_contact``.
    3. A number with the word ``hip``, ``knee`` or ``ankle`` and none of vel, velocity, speed, torque, effort,
       moment, force, current, power: ``<joint>_angle_deg``. In a ROS ``JointState`` only ``position[...]``
       counts and is radians (scale :data:`RAD_TO_DEG`); elsewhere degrees unless the word ``rad`` appears.
    4. ``angular_velocity.<x|y|z>`` / ``linear_acceleration.<x|y|z>`` on a topic with the word ``pelvis``,
       ``thigh``, ``shank`` or ``foot``: ``imu_<segment>_gyro_<axis>_dps`` from rad/s (ROS and Foxglove units,
       scale :data:`RAD_TO_DEG`) / ``imu_<segment>_accel_<axis>_m_s2`` unscaled. Axes are taken as they are:
       the other tool's IMU frame may differ from gaitscope's (``estimators/channels.py``).

    The word ``contra`` in the path or topic makes rules 2-4 pick the ``_contra`` channel. When two fields
    would feed one channel, the first rule wins, then the first field in ``fields``' order. The rig is the
    fields'; the time source is ``header`` when any field's topic was timed by its stamps.
    """
    ranked = sorted(
        ((r[0], i, f, r[1], r[2]) for i, f in enumerate(fields) if (r := _suggest_one(f)) is not None),
        key=lambda x: (x[0], x[1]),
    )
    entries: dict[str, MappingEntry] = {}
    for _, _, f, channel, scale in ranked:
        entries.setdefault(channel, MappingEntry(f.topic, f.path, channel, scale))
    header = any(f.time_source == "header" for f in fields)
    return ChannelMapping(tuple(entries.values()), fields[0].rig if fields else "", "header" if header else "log_time")


# ---------------------------------------------------------------------------------------------------------------
# Streaming
# ---------------------------------------------------------------------------------------------------------------


def _check(
    path: str | Path, name: str, mapping: ChannelMapping, allow_other_rig: bool, max_array: int
) -> dict[str, float]:
    """Check the mapping against the file (see :func:`foreign_frames`); the mapped topics' rates (Hz, 0 if
    unknown), in the mapping's order."""
    if not mapping.entries:
        raise MappingError("the mapping maps no fields")
    with open(path, "rb") as f:
        reader, summary = _open(f, name)
        topics = _topics(summary)
        if summary.statistics is not None and summary.statistics.message_count == 0:
            raise DataFormatError("the file holds no messages", file=name)
        rates: dict[str, float] = {}
        for e in mapping.entries:
            if e.topic in rates:
                continue
            if e.topic not in topics:
                close = difflib.get_close_matches(e.topic, list(topics), n=3, cutoff=0.5)
                hint = f"; close: {', '.join(close)}" if close else f"; its topics: {', '.join(topics)}"
                raise DataFormatError(f"the mapped topic {e.topic} is not in the file{hint}", file=name, column=e.topic)
            if why := next(filter(None, (_why_undecodable(summary, c) for c in topics[e.topic])), None):
                raise DataFormatError(f"the mapped topic {e.topic} carries {why}", file=name, column=e.topic)
            probe = list(_decode_errors(_sample(reader, e.topic, _PROBE), name, e.topic))
            if not probe:
                raise DataFormatError(f"the mapped topic {e.topic} has no messages", file=name, column=e.topic)
            clock = _Clock(mapping.time_source)
            leaves = [_flatten(d, max_array) for _, d in probe]
            times = [clock(t, lv) for (t, _), lv in zip(probe, leaves, strict=True)]
            rates[e.topic] = _rate(times) or 0.0
            for entry in (x for x in mapping.entries if x.topic == e.topic):
                _check_field(entry, next((lv for lv in leaves if entry.field in lv), leaves[0]), name)
        if mapping.rig and mapping.rig != _rig(summary) and not allow_other_rig:
            raise RigMismatch(
                "the mapping was made for recordings with other topics or message types (another rig); "
                "check it still fits, then use it anyway",
                file=name,
            )
    return rates


def _check_field(e: MappingEntry, leaves: Mapping[str, Leaf], name: str) -> None:
    where = f"{e.topic} {e.field}"
    value = leaves.get(e.field)
    if isinstance(value, str):
        raise DataFormatError(f"the mapped field is text ({value[:40]!r}), not a number", file=name, column=where)
    if value is None:
        inner = sorted(p for p in leaves if p.startswith((f"{e.field}.", f"{e.field}[")))
        if inner:
            what = f"has fields ({', '.join(inner[:6])}), it is not a number: map one of them"
        else:
            numeric = [p for p, v in leaves.items() if not isinstance(v, str)]
            close = difflib.get_close_matches(e.field, numeric, n=3, cutoff=0.5)
            what = f"is not in the topic's messages{'; close: ' + ', '.join(close) if close else ''}"
        raise DataFormatError(f"the mapped field {what}", file=name, column=where)


def foreign_frames(
    path: str | Path,
    name: str | None,
    mapping: ChannelMapping,
    rate_hz: float | None = None,
    *,
    stale_s: float = STALE_S,
    reorder_s: float = REORDER_S,
    allow_other_rig: bool = False,
    max_array: int = MAX_ARRAY,
) -> Iterator[schema.SensorFrame]:
    """The mapped file as sensor frames on one time base, read in log-time order with bounded memory.

    Time base: the times of the fastest mapped topic (judged on its first 50 messages; ties: the first in the
    mapping), or, with ``rate_hz``, a grid at that rate from the first mapped message to the last. Each frame
    takes every channel's latest value at or before its time (zero-order hold); a value more than ``stale_s``
    older than the frame is absent (None). ``heel_strike`` is an event, not held: each true message sets it on
    the first frame at or after its time, and the other frames say False (a held contact state belongs on
    ``foot_contact``). ``t`` (s) counts from 0 at the first frame, ``seq`` from 0. With header stamps
    (``mapping.time_source``), messages are put back in stamp order within ``reorder_s``; a message later than
    that still updates its channels but cannot change frames already made.

    A mapping from another rig (:attr:`ChannelMapping.rig` not this file's) raises :class:`RigMismatch`, a
    :class:`DataFormatError`, unless ``allow_other_rig``: the check itself is cheap, but a mapping that only
    happens to fit (same field names, other units) would give wrong numbers silently, so using it is the
    user's explicit choice. Problems are found here, before the first frame, from the first 50 messages of each
    mapped topic; only a message that cannot be decoded, or a mapped field that turns to text, is met later.

    Raises:
        DataFormatError: not MCAP or not finished; no messages; a mapped topic not in the file, without
            messages, or not decodable; a mapped field in none of its topic's first 50 messages (close names
            listed), text or a message rather than a number (``column`` names the topic and field; a later
            message without the field leaves its channel held); a message that cannot be decoded.
        RigMismatch: see above.
        MappingError: an empty mapping.
        ValueError: ``rate_hz`` not above 0, ``stale_s`` or ``reorder_s`` below 0.
    """
    if rate_hz is not None and not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz must be a finite number above 0, got {rate_hz}")
    if not (stale_s >= 0 and reorder_s >= 0):
        raise ValueError(f"stale_s and reorder_s must be at least 0, got {stale_s} and {reorder_s}")
    name = str(path) if name is None else name
    rates = _check(path, name, mapping, allow_other_rig, max_array)
    base = max(rates, key=lambda t: rates[t])  # max() keeps the first of equals
    return _stream(path, name, mapping, _Resampler(mapping, base, rate_hz, stale_s), reorder_s, max_array)


def _stream(
    path: str | Path, name: str, mapping: ChannelMapping, out: _Resampler, reorder_s: float, max_array: int
) -> Iterator[schema.SensorFrame]:
    by_topic: dict[str, list[MappingEntry]] = {}
    for e in mapping.entries:
        by_topic.setdefault(e.topic, []).append(e)
    clocks = {t: _Clock(mapping.time_source) for t in by_topic}
    stamps = _STAMP_LEAVES if mapping.time_source == "header" else ()
    wanted = {t: _prefixes([*(e.field for e in entries), *stamps]) for t, entries in by_topic.items()}
    rows = dict.fromkeys(by_topic, 0)
    reorder_ns = round(reorder_s * _NS) if mapping.time_source == "header" else 0
    pending: list[tuple[int, int, str, list[tuple[str, Leaf]]]] = []  # a heap by time, then arrival
    newest: int | None = None
    with open(path, "rb") as f:
        reader, _ = _open(f, name)
        messages = reader.iter_decoded_messages(topics=list(by_topic), log_time_order=True)
        for arrival, (_, channel, message, decoded) in enumerate(_decode_errors(messages, name, None)):
            topic = channel.topic
            rows[topic] += 1
            leaves = _flatten(decoded, max_array, wanted[topic])
            values: list[tuple[str, Leaf]] = []
            for e in by_topic[topic]:
                if isinstance(v := leaves.get(e.field), str):
                    msg = f"the mapped field is text ({v[:40]!r}) in this message, not a number"
                    raise DataFormatError(msg, file=name, column=f"{topic} {e.field}", row=rows[topic])
                if v is not None:
                    values.append((e.channel, v))
            t = clocks[topic](message.log_time, leaves)
            heapq.heappush(pending, (t, arrival, topic, values))
            newest = t if newest is None else max(newest, t)
            while pending and pending[0][0] <= newest - reorder_ns:
                yield from out.event(*_pop(pending))
    while pending:
        yield from out.event(*_pop(pending))
    yield from out.finish()


def _pop(heap: list[tuple[int, int, str, list[tuple[str, Leaf]]]]) -> tuple[int, str, list[tuple[str, Leaf]]]:
    t, _, topic, values = heapq.heappop(heap)
    return t, topic, values


class _Resampler:
    """Turns time-ordered (time, topic, values) events into frames on the time base (see :func:`foreign_frames`)."""

    def __init__(self, mapping: ChannelMapping, base: str, rate_hz: float | None, stale_s: float):
        self.base, self.rate_hz = base, rate_hz
        self.stale_ns = round(stale_s * _NS) if math.isfinite(stale_s) else None
        self.scale = {e.channel: (e.scale, e.offset) for e in mapping.entries}
        self.strikes = "heel_strike" in self.scale
        self.latest: dict[str, tuple[int, float | bool]] = {}
        self.strike = False  # a heel strike waits for the next frame
        self.pending: int | None = None  # the base topic's time of the frame not yet made
        self.grid0: int | None = None
        self.k = 0  # frames made
        self.t0: int | None = None
        self.last = 0  # latest event time
        self.made: int | None = None  # time of the last frame made

    def _grid(self, k: int) -> int:
        assert self.grid0 is not None and self.rate_hz is not None
        return self.grid0 + round(k * _NS / self.rate_hz)

    def event(self, t: int, topic: str, values: Sequence[tuple[str, Leaf]]) -> Iterator[schema.SensorFrame]:
        if self.rate_hz is not None:
            if self.grid0 is None:
                self.grid0 = t
            while self._grid(self.k) < t:
                yield self._frame(self._grid(self.k))
        elif self.pending is not None and t > self.pending:
            yield self._frame(self.pending)
            self.pending = None
        self.last = max(self.last, t)
        for channel, v in values:
            if channel == "heel_strike":
                self.strike = self.strike or bool(v)
            elif channel in self.latest and self.latest[channel][0] > t:
                continue  # a message later than reorder_s: older than the value held
            elif _is_flag(channel):
                self.latest[channel] = (t, bool(v))
            else:
                scale, offset = self.scale[channel]
                self.latest[channel] = (t, float(v) * scale + offset)
        if self.rate_hz is None and topic == self.base and (self.made is None or t > self.made):
            self.pending = t

    def finish(self) -> Iterator[schema.SensorFrame]:
        if self.rate_hz is not None:
            while self.grid0 is not None and self._grid(self.k) <= self.last:
                yield self._frame(self._grid(self.k))
        elif self.pending is not None:
            yield self._frame(self.pending)

    def _frame(self, at: int) -> schema.SensorFrame:
        self.t0 = at if self.t0 is None else self.t0
        self.made = at
        values: dict[str, float | bool | None] = {
            c: v for c, (tv, v) in self.latest.items() if self.stale_ns is None or at - tv <= self.stale_ns
        }
        if self.strikes:
            values["heel_strike"], self.strike = self.strike, False
        frame = schema.SensorFrame(seq=self.k, t=(at - self.t0) / _NS, **values)
        self.k += 1
        return frame
