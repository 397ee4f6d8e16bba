"""Replay a recorded trial through any stack of registered estimators (``gaitscope replay --estimators``).

Where :mod:`gaitscope.sessions.offline.replay` runs the fixed stack of ``phase_ekf`` and ``tbe`` into fixed columns,
this runs the estimators a researcher names (or ``all`` the file's channels feed) and writes every output of each
as a ``<name>.<output>`` column, so that any seed method can be scored on one's own data. It builds no second
implementation: the trial's rows become :class:`~gaitscope.sessions.schema.SensorFrame` s stepped through a live
session's :class:`~gaitscope.sessions.estimation.FrameEstimator` at the file's median sample period (the registry's
stack, velocities a file lacks by backward difference, implausible values treated as missing), so a replay and a
live session of the same frames give the same numbers, bit for bit (``tests/sessions/offline/test_replay_stack.py``).
As in :mod:`~gaitscope.sessions.offline.replay`, a live session's soft start and intent boost are off:
``torque_Nm`` is the stack's command at the given gain from the first sample.

The stack is built, and refused, before anything is written: an unknown name (the known ones are listed), an
estimator whose required channels the file lacks (the registry's :class:`~gaitscope.sessions.registry.MissingChannels`
message names them) or that cannot be built (``fp_ls`` without a subject's fingerprint), or a stack with no phase
estimator to drive the torque. The output is written atomically, in parts of :data:`PART` samples.
"""

from __future__ import annotations

import csv
import itertools
import math
import time
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from gaitscope.estimators.pipeline import PipelineConfig, TrainedModel
from gaitscope.sessions import schema
from gaitscope.sessions.estimation import FrameEstimator
from gaitscope.sessions.files import atomic_output

# the replay output's own formatter (floats as their shortest round-trip repr, NaN as ``nan``), so that a column
# here is written byte for byte as the same column of ``gaitscope replay``
from gaitscope.sessions.formats._fastcsv import format_rows
from gaitscope.sessions.formats.replay_io import ReplayInput, read_replay_csv
from gaitscope.sessions.registry import (
    DECLARED,
    ESTIMATORS,
    MissingChannels,
    StackContext,
    Unavailable,
    feeds,
)

__all__ = [
    "ALL",
    "PART",
    "EstimatorSummary",
    "StackReplay",
    "StackReplaySummary",
    "file_channels",
    "replay_estimators",
    "replay_input_estimators",
    "stack_names",
]

#: ``--estimators all``: every registered estimator the file's channels feed and the session can build.
ALL: Final = "all"
#: Samples per part of the output: each part is formatted and written before the next is estimated.
PART: Final = 8192
#: The columns before the estimators' outputs.
LEADING: Final = (schema.REPLAY_TIME, "torque_Nm")
#: Notes of the frame estimator (resynchronisations, restarts, standing still) shown in a summary; the rest counted.
_NOTES_SHOWN: Final = 5


@dataclass(frozen=True)
class EstimatorSummary:
    """What one estimator of the stack gave over the trial.

    Attributes:
        name: its registry name; ``label`` its name on screen.
        outputs: its output names, in its columns' order (``<name>.<output>``).
        samples: samples where it gave a finite value of its first output.
        mean_phase_rate: mean of its finite ``phase_rate`` values (1/s); None without that output or value.
        first_range: ``(min, max)`` of its first output's finite values; None without any.
        failed: why the stack marked it failed (it gave NaN from then on); None while healthy.
    """

    name: str
    label: str
    outputs: tuple[str, ...]
    samples: int
    mean_phase_rate: float | None
    first_range: tuple[float, float] | None
    failed: str | None = None

    def line(self, total: int) -> str:
        """One line: how many samples have a value, and its mean phase rate or the range of its first output."""
        if self.mean_phase_rate is not None:
            what = f"mean phase rate {self.mean_phase_rate:.3f} /s"
        elif self.first_range is not None:
            what = f"{self.outputs[0]} {self.first_range[0]:.3g} .. {self.first_range[1]:.3g}"
        else:
            what = "no value"
        failed = f"; failed: {self.failed}" if self.failed else ""
        return f"{self.name:<16} {self.samples}/{total} samples with a value; {what}{failed}"


@dataclass(frozen=True)
class StackReplaySummary:
    """What a replay of a named stack did, for the command line and for logs."""

    samples: int
    duration_s: float
    channels: tuple[str, ...]  #: the file's channels (``heel_strike`` included when it has the column)
    primary: str | None  #: the estimator the torque followed at the end
    columns: tuple[str, ...]  #: the output's columns, in order
    estimators: tuple[EstimatorSummary, ...]  #: in stack order
    peak_torque_Nm: float
    wall_s: float
    events: tuple[str, ...] = ()  #: the stack's (failures, primary switches)
    notes: tuple[str, ...] = ()  #: the frame estimator's (restarts, standing still)
    ignored: tuple[str, ...] = ()  #: the file's columns that are not channels (not read)

    def lines(self) -> list[str]:
        more = len(self.notes) - _NOTES_SHOWN
        return [
            f"samples          {self.samples} over {self.duration_s:.1f} s",
            f"channels         {', '.join(self.channels)}",
            f"stack            {', '.join(e.name for e in self.estimators)} (torque follows {self.primary})",
            *(f"estimator        {e.line(self.samples)}" for e in self.estimators),
            f"peak torque      {self.peak_torque_Nm:.1f} N m",
            f"columns          {len(self.columns)}",
            f"wall time        {self.wall_s:.2f} s ({self.samples / max(self.wall_s, 1e-9):,.0f} samples/s)",
            *(f"event            {e}" for e in self.events),
            *(f"note             {n}" for n in self.notes[:_NOTES_SHOWN]),
            *([f"note             ... and {more} more"] if more > 0 else []),
            *([f"ignored          {', '.join(self.ignored)} (not channels)"] if self.ignored else []),
        ]


def file_channels(data: ReplayInput) -> set[str]:
    """The channels (of :data:`~gaitscope.sessions.schema.CHANNELS`) a trial sends: its signals, and
    ``heel_strike`` when it has the column."""
    out = {c for c in data.signals if c in schema.CHANNELS}
    if data.heel_strike is not None:
        out.add(schema.REPLAY_HEEL_STRIKE)
    return out


def stack_names(names: Sequence[str], channels: Collection[str], ctx: StackContext) -> list[str]:
    """The estimators to run: ``names`` as given, or for ``[ALL]`` every registered one (opt-in ones too) that
    ``channels`` feed (:func:`~gaitscope.sessions.registry.feeds`) and ``ctx`` can build, in registry order.

    Raises:
        ValueError: no name, or ``all`` beside other names.
    """
    names = [n.strip() for n in names if n.strip()]
    if not names:
        raise ValueError(f"name at least one estimator, or {ALL}; gaitscope has {', '.join(ESTIMATORS)}")
    if ALL not in names:
        return names
    if len(names) > 1:
        raise ValueError(f"{ALL} stands alone: it runs every estimator the file's channels feed")
    out = []
    for name, feed in feeds(channels).items():
        if feed.missing:
            continue
        try:
            ESTIMATORS[name](ctx)
        except Unavailable:  # fp_ls without a subject's fingerprint
            continue
        out.append(name)
    return out


class StackReplay:
    """A trial stepped through a live session's :class:`FrameEstimator` of the estimators ``names``, part by part.

    Args:
        data: the trial; ``signals`` may hold any channel of :data:`~gaitscope.sessions.schema.CHANNELS`
            (flags as 0/1), others are ignored.
        model: the trained models; ``config``: the subject (leg length, mass) and the assistance (torque
            gain, bound). The estimators are built as the registry builds them for a session.
        names: estimators (run in registry order), or ``[ALL]``.
        fingerprint: the subject's personalized gait fingerprint (for ``fp_ls``).

    Attributes:
        estimator: the frame estimator (``estimator.stack`` the stack).
        columns: the output's columns: :data:`LEADING`, then per estimator in stack order ``<name>.<output>``.
        spans: per estimator in stack order, where its columns start and end (``columns[lo:hi]``).

    Raises:
        ValueError: an unknown or repeated name (the known ones listed), ``all`` beside other names, or a
            stack without a phase estimator.
        MissingChannels: an estimator the trial's channels cannot feed (naming them), or that cannot be built.
    """

    def __init__(
        self,
        data: ReplayInput,
        model: TrainedModel,
        config: PipelineConfig,
        names: Sequence[str],
        fingerprint: Sequence[float] | None = None,
    ):
        self.data = data
        period = float(np.median(np.diff(data.time_s))) if data.time_s.size > 1 else 0.01
        channels = file_channels(data)
        ctx = StackContext(
            model, config.leg_length, config.body_mass_kg, period, None if fingerprint is None else tuple(fingerprint)
        )
        self.names = stack_names(names, channels, ctx)
        settings = schema.SessionSettings(
            torque_gain=config.torque_gain, max_torque_Nm=config.max_torque, primary=_primary(self.names)
        )
        try:
            self.estimator = FrameEstimator(
                model,
                config.leg_length,
                config.body_mass_kg,
                settings,
                period,
                0.0,  # session time is the file's time
                soft_start=False,
                max_jump_s=math.inf,  # a file's times are trusted: a pause stays a pause
                estimators=self.names,
                channels=channels,
                fingerprint=fingerprint,
            )
        except MissingChannels as e:
            raise MissingChannels(f"{e}{_derive_hint(self.names, channels)}") from None
        except ValueError as e:
            known = [n for n in self.names if n in DECLARED]
            if len(known) == len(self.names) and not any(_phased(n) for n in known):
                raise ValueError(
                    f"{e}: the replay's torque_Nm follows a phase estimator; add one (phased: "
                    f"{', '.join(n for n in ESTIMATORS if _phased(n))})"
                ) from None
            raise
        stack = self.estimator.stack
        self.columns: tuple[str, ...] = (
            *LEADING,
            *(f"{name}.{o}" for name, outs in zip(stack.names, stack.outputs, strict=True) for o in outs),
        )
        ends = np.cumsum([len(LEADING), *(len(o) for o in stack.outputs)]).tolist()
        self.spans = list(itertools.pairwise(ends))
        self._signals = [c for c in data.signals if c in schema.CHANNELS and c != schema.REPLAY_HEEL_STRIKE]
        self._flags = {c for c in self._signals if schema.CHANNELS[c].unit == "bool"}
        self.notes: list[str] = []
        self.events: list[str] = list(self.estimator.events)
        self.estimator.events.clear()

    def estimate(self, a: int, b: int) -> NDArray[np.float64]:
        """Samples ``a`` to ``b``: ``(b - a, len(columns))``, NaN where an estimator gave no value (failed)."""
        est, spans, flags = self.estimator, self.spans, self._flags
        out = np.full((b - a, len(self.columns)), np.nan)
        out[:, 0] = self.data.time_s[a:b]
        t = self.data.time_s[a:b].tolist()
        rows = np.column_stack([self.data.signals[c][a:b] for c in self._signals]).tolist() if self._signals else None
        hs = None if self.data.heel_strike is None else self.data.heel_strike[a:b].tolist()
        for k, tk in enumerate(t):
            fields: dict[str, Any] = {} if rows is None else dict(zip(self._signals, rows[k], strict=True))
            for c in flags:
                fields[c] = fields[c] >= 0.5
            if hs is not None:
                fields[schema.REPLAY_HEEL_STRIKE] = bool(hs[k])
            state = est.step(schema.SensorFrame(seq=a + k, t=tk, **fields), 0)
            out[k, 1] = state.torque_Nm
            assert est.last is not None
            for (lo, hi), y in zip(spans, est.last.outputs, strict=True):
                if y is not None:
                    out[k, lo:hi] = y
            if est.notes:
                self.notes.extend(est.notes)
                est.notes.clear()
            if est.events:
                self.events.extend(est.events)
                est.events.clear()
        return out


def replay_input_estimators(
    data: ReplayInput,
    output_path: str | Path,
    model: TrainedModel,
    config: PipelineConfig,
    names: Sequence[str],
    fingerprint: Sequence[float] | None = None,
    *,
    started: float | None = None,
) -> StackReplaySummary:
    """Replay ``data`` through the estimators ``names`` into ``output_path`` (see :class:`StackReplay`).

    The stack is built (or refused) before the output is opened; the output is written beside
    ``output_path`` and moved over it at the end, so an error leaves ``output_path`` as it was.
    ``started``: when the replay started (``time.perf_counter``; default now), for the summary's wall time.

    Raises:
        ValueError, MissingChannels: as :class:`StackReplay`.
    """
    start = time.perf_counter() if started is None else started
    replay = StackReplay(data, model, config, names, fingerprint)
    n = data.time_s.size
    width = len(replay.columns)
    finite = np.zeros(width, dtype=np.int64)
    lo, hi = np.full(width, np.inf), np.full(width, -np.inf)
    total = np.zeros(width)
    with atomic_output(Path(output_path)) as tmp:
        with tmp.open("w", newline="") as header:
            csv.writer(header, lineterminator="\n").writerow(replay.columns)
        with tmp.open("ab") as file:
            for a in range(0, n, PART):
                part = replay.estimate(a, min(a + PART, n))
                ok = np.isfinite(part)
                finite += ok.sum(axis=0)
                lo = np.minimum(lo, np.where(ok, part, np.inf).min(axis=0))
                hi = np.maximum(hi, np.where(ok, part, -np.inf).max(axis=0))
                total += np.where(ok, part, 0.0).sum(axis=0)
                file.write(format_rows(list(part.T)))
    stack = replay.estimator.stack
    summaries = []
    for (first, _), name, outs in zip(replay.spans, stack.names, stack.outputs, strict=True):
        rate = first + outs.index("phase_rate") if "phase_rate" in outs else None
        summaries.append(
            EstimatorSummary(
                name=name,
                label=stack.labels[name],
                outputs=tuple(outs),
                samples=int(finite[first]),
                mean_phase_rate=None if rate is None or not finite[rate] else float(total[rate] / finite[rate]),
                first_range=(float(lo[first]), float(hi[first])) if finite[first] else None,
                failed=stack.failed.get(name),
            )
        )
    return StackReplaySummary(
        samples=n,
        duration_s=float(data.time_s[-1] - data.time_s[0]),
        channels=tuple(sorted(file_channels(data))),
        primary=stack.primary,
        columns=replay.columns,
        estimators=tuple(summaries),
        peak_torque_Nm=float(hi[1]) if finite[1] else 0.0,
        wall_s=time.perf_counter() - start,
        events=tuple(replay.events),
        notes=tuple(replay.notes),
        ignored=data.ignored,
    )


def replay_estimators(
    input_path: str | Path,
    output_path: str | Path,
    model: TrainedModel,
    config: PipelineConfig,
    names: Sequence[str],
    fingerprint: Sequence[float] | None = None,
) -> StackReplaySummary:
    """Replay the CSV ``input_path`` through the estimators ``names`` (or ``["all"]``) into ``output_path``.

    Reads the input with full validation (:func:`~gaitscope.sessions.formats.replay_io.read_replay_csv`, which
    refuses a file that feeds none of the named estimators); nothing is written if it is invalid or the stack is
    refused (:func:`replay_input_estimators`).

    Raises:
        DataFormatError: the input file (naming its row and column).
        ValueError, MissingChannels: as :class:`StackReplay`.
    """
    started = time.perf_counter()
    named = [n.strip() for n in names if n.strip() and n.strip() != ALL]
    data = read_replay_csv(input_path, estimators=[n for n in named if n in ESTIMATORS])  # all: any channel
    return replay_input_estimators(data, output_path, model, config, names, fingerprint, started=started)


def _phased(name: str) -> bool:
    return DECLARED[name].phased


def _primary(names: Sequence[str]) -> str:
    """The torque follows ``phase_ekf`` (a session's default primary) when named, else the first named estimator
    with a phase in registry order (the stack's own choice, without the event saying it is not the default)."""
    default = schema.SessionSettings().primary
    if default in names:
        return default
    return next((n for n in ESTIMATORS if n in names and _phased(n)), default)


def _derive_hint(names: Sequence[str], channels: Collection[str]) -> str:
    """For a refused stack: the required channels the file lacks that estimators not named would derive."""
    hints = []
    for name, feed in feeds(channels).items():
        if name not in names:
            continue
        for channel, by in feed.derived.items():
            if not any(d in names for d in by):
                hints.append(f"{channel} for {name}: name {' or '.join(by)} with it (they derive it)")
    return f" ({'; '.join(hints)})" if hints else ""
