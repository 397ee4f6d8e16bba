"""IMU problems in the clinician's words: session events and a data-health line from the IMU front ends.

Each IMU front end of the stack (:class:`gaitscope.estimators.imu_frontend.ImuFrontEnd`) says per sample what was wrong
with its sensor's reading (its ``imu_code`` output, :data:`gaitscope.estimators.imu_frontend.CODES`) and degrades its
estimate safely on its own (angle held, or taken from the accelerometer alone). One sample's code says
little: a single frame without the sensor, one spike at the gyro's full scale, one late frame.
:class:`ImuWatch` turns the codes into **episodes**, per sensor and problem:

- a problem **starts** when its code covers at least ``onset_s`` (0.3 s) of the last ``window_s`` (1 s)
  of session time, each sample counting for the time since the sample before it (at most
  :data:`~gaitscope.estimators.protocol.MAX_GAP_S`, after which the estimators restart anyway; the session's first
  sample for nothing). So a fault that lasts is reported 0.3 s after it began, whatever the sample rate;
  an intermittent one (a gyro that saturates at every swing's peak) once it covers 30 % of a second; an
  isolated bad sample, or a few of them, never;
- it **ends** when its code was not reported at all for a whole ``window_s``: a problem that comes and
  goes within a second is one episode, not many;
- each start and each end is one event (:class:`ImuEvent`), so a sensor and problem give at most one pair
  of events per ``onset_s + window_s`` of session time, however noisy the stream. The same change in the
  same words on several sensors at one sample is one event naming them all (a wrong sample rate: every
  sensor of the device sees it);
- data health shows the worst open problem (:data:`SEVERITY`, then stack order) on one line, naming every
  sensor with the same, and how many more are open (:meth:`ImuWatch.health`).

Sensors are named by the subject's side (``Right shank IMU``; the ``_contra`` ones the other side's).
:data:`PROBLEMS` is the one place that says what each code means in the clinician's words. A front end
that fails (the stack isolates it, and data health lists it) is no longer watched: its open problems stay
open.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final, Literal

import numpy as np
from numpy.typing import NDArray

from gaitscope.estimators.imu_frontend import CODES, ImuFrontEnd
from gaitscope.estimators.protocol import MAX_GAP_S
from gaitscope.sessions import schema
from gaitscope.sessions.live.extensions import Outputs, SessionExtension, SessionHost

__all__ = ["ONSET_S", "PROBLEMS", "SEVERITY", "WINDOW_S", "ImuEvent", "ImuEvents", "ImuWatch", "Problem"]

#: A problem covering this much of the last ``window_s`` of session time starts an episode (s).
ONSET_S: Final = 0.3
#: The window over which a problem's share is measured; a problem absent from a whole window has ended (s).
WINDOW_S: Final = 1.0
#: The name of ``imu_code`` 0 (no problem) in an event's before / after.
OK: Final = "ok"


@dataclass(frozen=True)
class Problem:
    """What an ``imu_code`` means, for a clinician.

    Attributes:
        short: a few words, for a recovery (``gyro saturated``).
        text: the sensor's problem and what the estimate does about it, a ``str.format`` template of
            ``angle`` (``shank angle``), ``since_s`` (how long the problem has lasted), ``full_scale_dps``
            (the gyro's full scale), ``every_ms`` (the mean interval of the samples flagged, recent) and
            ``expected_ms`` (the interval the front end expects: the session's declared rate).
    """

    short: str
    text: str


#: Every non-zero ``imu_code`` (by its :data:`~gaitscope.estimators.imu_frontend.CODES` name) in the clinician's words.
PROBLEMS: Final[dict[str, Problem]] = {
    "missing": Problem("no data", "no data for {since_s:.1f} s; {angle} held"),
    "gyro_saturated": Problem(
        "gyro saturated",
        "gyro saturated (reading at the sensor's full scale, {full_scale_dps:g} deg/s); {angle} from the "
        "accelerometer alone",
    ),
    "accel_implausible": Problem(
        "accelerometer implausible",
        "accelerometer upside down, an axis flipped or reading out of range; check the mounting; {angle} unreliable",
    ),
    "sample_rate": Problem(
        "wrong sample rate",
        "samples arrive every {every_ms:.3g} ms, expected {expected_ms:.3g} ms; check the device's sample rate",
    ),
    "disagree": Problem(
        "gyro and accelerometer disagree",
        "gyro and accelerometer disagree (a flipped gyro axis, or the sensor moved on the segment); check the "
        "mounting; {angle} unreliable",
    ),
}
#: Problems worst first, for data health: no data at all; an accelerometer that misleads the angle; the
#: sensors contradicting each other; a saturated gyro (the accelerometer carries the angle); a wrong rate
#: (the front end integrates the intervals it gets, but the session's filters assume the declared rate).
SEVERITY: Final = ("missing", "accel_implausible", "disagree", "gyro_saturated", "sample_rate")


@dataclass(frozen=True)
class ImuEvent:
    """A problem that started or ended at this sample, for the session's event log.

    Attributes:
        estimators: the front ends (``imu_shank``); several when the same problem, in the same words, started
            or ended on several at the same sample (a wrong sample rate: every sensor of a device sees it).
        before, after: the problem's code name (:data:`~gaitscope.estimators.imu_frontend.CODES`) and :data:`OK`,
            in that order when it ended, the other way round when it started.
        text: what happened, naming the sensors (``Right shank IMU: gyro saturated ...``).
    """

    estimators: tuple[str, ...]
    before: str
    after: str
    text: str

    @property
    def field(self) -> str:
        """The event's ``field``: the front ends, comma-separated."""
        return ",".join(self.estimators)


class _Sensor:
    """One front end's recent problem samples and open episodes."""

    def __init__(self, k: int, column: int, front_end: ImuFrontEnd, side: str | None):
        self.k, self.column, self.front_end = k, column, front_end
        base, _, contra = front_end.segment.partition("_")
        #: how a label names it: (side, segment), e.g. ("right", "shank"); ("other leg's", "shank") when the
        #: subject's side is unknown
        other = {"left": "right", "right": "left"}.get(side or "", "other leg's")
        self.part = ((other if contra else side) or "", base)
        self.angle = f"{base} angle"
        #: samples with a problem within the window: (t, weight, code)
        self.recent: deque[tuple[float, float, int]] = deque()
        self.held = [0.0] * len(CODES)  # per code: the weights in the window (s)
        self.count = [0] * len(CODES)  # per code: the samples in the window
        self.open: dict[int, tuple[float, float]] = {}  # per open code: (since, last seen)

    def words(self, code: int, t: float) -> str:
        """The open problem ``code`` at session time ``t``, in the clinician's words (without the sensor)."""
        c = self.front_end.config
        since, _ = self.open.get(code, (t, t))
        every = self.held[code] / self.count[code] if self.count[code] else 0.0
        return PROBLEMS[CODES[code]].text.format(
            angle=self.angle,
            since_s=t - since,
            full_scale_dps=c.gyro_full_scale_dps,
            every_ms=every * 1e3,
            expected_ms=c.sample_period * 1e3,
        )


class ImuWatch:
    """Watches the IMU front ends of a stack, sample by sample (see the module docstring).

    Args:
        estimators: the stack's estimators, in stack order (the front ends among them are watched).
        outputs: each one's output names, in the order it returns them.
        side: the subject's instrumented side (``right``: its sensors are the right ones, the ``_contra``
            ones the left); None: ``Shank IMU`` and ``Other leg's shank IMU``.
        onset_s: how much of the last ``window_s`` a problem must cover to start (s).
        window_s: the window; a problem absent from a whole window has ended (s).

    Raises:
        ValueError: ``onset_s`` not within ``(0, window_s]``.
    """

    def __init__(
        self,
        estimators: Sequence[object],
        outputs: Sequence[Sequence[str]],
        side: str | None = None,
        onset_s: float = ONSET_S,
        window_s: float = WINDOW_S,
    ):
        if not 0.0 < onset_s <= window_s:
            raise ValueError(f"onset_s must be within (0, window_s = {window_s:g}], got {onset_s}")
        self.onset_s, self.window_s = onset_s, window_s
        self._sensors = [
            _Sensor(k, list(outs).index("imu_code"), est, side)
            for k, (est, outs) in enumerate(zip(estimators, outputs, strict=True))
            if isinstance(est, ImuFrontEnd) and "imu_code" in outs
        ]
        self._t: float | None = None

    @property
    def active(self) -> bool:
        """Whether the stack has IMU front ends."""
        return bool(self._sensors)

    def update(self, t: float, outputs: Sequence[NDArray[np.float64] | None]) -> list[ImuEvent]:
        """One sample at session time ``t`` with every estimator's outputs
        (:attr:`gaitscope.sessions.stack.StackSample.outputs`); the problems that started or ended at it. A few
        comparisons per front end while its sensor is fine."""
        weight = 0.0 if self._t is None else min(max(t - self._t, 0.0), MAX_GAP_S)
        self._t = t
        changes: list[tuple[_Sensor, str, str, str]] = []  # (sensor, before, after, words)
        for s in self._sensors:
            y = outputs[s.k] if s.k < len(outputs) else None
            if y is None:
                continue  # failed: data health lists it
            code = int(y[s.column]) if weight > 0 else 0  # the first sample: no interval to count for
            if 0 < code < len(CODES):
                s.recent.append((t, weight, code))
                s.held[code] += weight
                s.count[code] += 1
                if code in s.open:
                    s.open[code] = (s.open[code][0], t)
            recent = s.recent
            while recent and recent[0][0] <= t - self.window_s:
                _, w, c = recent.popleft()
                s.count[c] -= 1
                s.held[c] = s.held[c] - w if s.count[c] else 0.0  # no rounding left over
            if 0 < code < len(CODES) and code not in s.open and s.held[code] >= self.onset_s - 1e-9:
                s.open[code] = (next(t0 for t0, _, c in recent if c == code), t)
                changes.append((s, OK, CODES[code], s.words(code, t)))
            if s.open and any(s.count[c] == 0 for c in s.open):
                ended = {c: s.open.pop(c) for c in list(s.open) if s.count[c] == 0}
                for c, (since, last) in ended.items():
                    changes.append((s, CODES[c], OK, _ended(s, c, last - since)))
        return _grouped(changes) if changes else []

    def open(self) -> list[tuple[str, str]]:
        """The open problems as ``(front end, code name)``, worst first (:data:`SEVERITY`, then stack order)."""
        found = [(SEVERITY.index(CODES[c]), n, s.front_end.name, CODES[c]) for n, s in enumerate(self._sensors)
                 for c in s.open]  # fmt: skip
        return [(name, code) for _, _, name, code in sorted(found)]

    def health(self) -> tuple[Literal["ok", "fault"] | None, str]:
        """Data health's IMU line (:class:`~gaitscope.sessions.schema.Health` ``imu``, ``imu_note``): None without front
        ends; ``ok``; or ``fault`` and the worst open problem's words now (naming every sensor with the same
        words), and how many more are open."""
        if not self._sensors:
            return None, ""
        found = self.open()
        if not found:
            return "ok", ""
        by_name = {s.front_end.name: s for s in self._sensors}
        t = self._t or 0.0
        said = [(by_name[name], by_name[name].words(CODES.index(code), t)) for name, code in found]
        same = [s for s, words in said if words == said[0][1]]
        note = f"{_label([s.part for s in same])}: {said[0][1]}"
        more = len(found) - len(same)
        if more:
            note += f" (and {more} more IMU problem{'s' if more > 1 else ''})"
        return "fault", note

class ImuEvents(SessionExtension):
    """The session extension: the episodes of the stack's front ends as system events (stored without making
    the sample wait), and data health's IMU line (``imu``, ``imu_note``)."""

    def __init__(self, host: SessionHost):
        self.host = host
        stack = host.estimator.stack
        self.watch = ImuWatch(stack.estimators, stack.outputs, host.subject.side)

    def on_sample(self, state: schema.GaitState, outputs: Outputs) -> None:
        if self.watch.active:
            for imu in self.watch.update(state.t, outputs):
                self.host.event_soon("system", imu.text, field=imu.field, before=imu.before, after=imu.after)

    def health(self) -> dict[str, object]:
        imu, note = self.watch.health()
        return {"imu": imu, "imu_note": note}



def _ended(s: _Sensor, code: int, lasted_s: float) -> str:
    """The words for a problem of sensor ``s`` that ended after ``lasted_s``: recovered, or what is still open."""
    short = PROBLEMS[CODES[code]].short
    if not s.open:
        return f"recovered ({short} for {lasted_s:.1f} s)"
    still = ", ".join(PROBLEMS[CODES[c]].short for c in sorted(s.open))
    return f"{short} over after {lasted_s:.1f} s; still {still}"


def _grouped(changes: list[tuple[_Sensor, str, str, str]]) -> list[ImuEvent]:
    """One event per change and words, naming every sensor it happened to (in stack order)."""
    groups: dict[tuple[str, str, str], list[_Sensor]] = {}
    for s, before, after, words in changes:
        groups.setdefault((before, after, words), []).append(s)
    return [
        ImuEvent(
            tuple(s.front_end.name for s in sensors), before, after, f"{_label([s.part for s in sensors])}: {words}"
        )
        for (before, after, words), sensors in groups.items()
    ]


def _label(parts: list[tuple[str, str]]) -> str:
    """``Right shank IMU``; ``Right foot, shank and thigh IMUs``; ``Right foot and left shank IMUs``."""
    sides = {side for side, _ in parts}
    names = [base for _, base in parts] if len(sides) == 1 else [f"{side} {base}".strip() for side, base in parts]
    joined = names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"
    text = f"{parts[0][0]} {joined}".strip() if len(sides) == 1 else joined
    return f"{text[:1].upper()}{text[1:]} IMU{'s' if len(parts) > 1 else ''}"
