"""What a log's channels can feed, and whether its values look like what their names say.

:func:`report` is an import's answer (:class:`~gaitscope.sessions.schema.ImportReport`): the channels the file
sends, those computed from them (an angle's velocity, by the backward difference live sessions use), the
columns not read, and for every registered estimator whether the file feeds it (the registry's one rule,
:func:`gaitscope.sessions.registry.feeds`) and what it lacks.

:class:`Plausibility` checks the values as they stream past (bounded memory) and names what it finds in the
user's terms: a column whose values mostly fall outside its channel's plausible range (a heel position in mm
where metres are meant), an angle column whose whole range is that of radians, a knee that hyperextends
beyond :data:`KNEE_HYPEREXTENSION_DEG` (a knee angle whose sign is extension-positive), a walking foot angle
more toes-up than toes-down (:data:`FOOT_WALKING_SPAN_DEG`: its sign reversed). Some are refusals
(:meth:`Plausibility.refusal`: the import stores nothing), the rest warnings in the report.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Iterable, Sequence
from dataclasses import dataclass
from typing import Final

from gaitscope.estimators.protocol import ANGLE_CHANNELS
from gaitscope.sessions import schema

__all__ = [
    "FOOT_WALKING_SPAN_DEG",
    "KNEE_HYPEREXTENSION_DEG",
    "OUTSIDE_REFUSED",
    "Plausibility",
    "derived_channels",
    "report",
]

#: A knee angle this far below 0 (deg, hyperextension) in more than 1 % of the samples is refused: the
#: knee's sign is flexion-positive in gaitscope's channels; walking hyperextends a few degrees at most.
KNEE_HYPEREXTENSION_DEG: Final = -40.0
#: A channel with more than this fraction of its values outside its plausible range is refused: its unit or
#: scale is not the one its name says (values outside the range are otherwise treated as missing, as live).
OUTSIDE_REFUSED: Final = 0.5
#: An angle column (deg) of at least this many samples whose whole range is within +/- pi and spans under
#: this many degrees is reported as probably in radians (a warning: standing still looks the same).
_RADIANS_SPAN_DEG: Final = 3.2
_RADIANS_MIN_SAMPLES: Final = 500
_KNEE: Final = ("knee_angle_deg", "knee_angle_contra_deg")
_FOOT: Final = ("foot_angle_deg", "foot_angle_contra_deg")
#: A foot angle spanning more than this (deg: walking) whose toes-up extreme exceeds its toes-down one is
#: refused: in walking the foot is steepest toes-down at toe-off (-60 to -80 deg in the cohort and in a real
#: Vicon walk, +10 to +30 toes-up at heel strike), so the column's sign is reversed.
FOOT_WALKING_SPAN_DEG: Final = 40.0


def derived_channels(channels: Collection[str]) -> list[str]:
    """The velocities a stream computes from its angles (the angle sent, its velocity not)."""
    return [vel for angle, vel in ANGLE_CHANNELS.items() if angle in channels and vel not in channels]


def report(
    fmt: str,
    channels: Collection[str],
    ran: Sequence[str],
    ignored: Sequence[str] = (),
    warnings: Sequence[str] = (),
) -> schema.ImportReport:
    """An import's report: ``channels`` sent, the stack it ``ran`` (names), the file's ``ignored`` columns."""
    from gaitscope.sessions.registry import DECLARED, feeds  # the estimators' registry: only when a file is read

    sent = [c for c in schema.CHANNELS if c in channels]
    fed = feeds(sent)
    estimators = [
        schema.EstimatorFeed(
            name=name,
            label=DECLARED[name].label,
            feedable=not f.missing,
            ran=name in ran,
            missing=list(f.missing),
            derived={c: list(by) for c, by in f.derived.items()},
        )
        for name, f in fed.items()
    ]
    return schema.ImportReport(
        format=fmt,
        channels=sent,
        derived=derived_channels(sent),
        ignored=list(ignored),
        estimators=estimators,
        warnings=list(warnings),
    )


@dataclass
class _Seen:
    n: int = 0
    outside: int = 0
    low: float = math.inf
    high: float = -math.inf
    hyperextended: int = 0


class Plausibility:
    """Checks a stream's values against their channels as frames go past (:meth:`add`).

    Args:
        channels: the channels to check (those the file sends; flags are skipped).
    """

    def __init__(self, channels: Collection[str]):
        self._checked = [c for c in schema.CHANNELS if c in channels and c in schema.SENSOR_LIMITS]
        self._seen = {c: _Seen() for c in self._checked}

    def add(self, frames: Iterable[schema.SensorFrame]) -> None:
        """Count ``frames``' values."""
        for frame in frames:
            for c in self._checked:
                v = getattr(frame, c)
                if v is None:
                    continue
                s = self._seen[c]
                lo, hi = schema.SENSOR_LIMITS[c]
                s.n += 1
                if not lo <= v <= hi:
                    s.outside += 1
                    continue
                s.low = min(s.low, v)
                s.high = max(s.high, v)
                if c in _KNEE and v < KNEE_HYPEREXTENSION_DEG:
                    s.hyperextended += 1

    def summary(self) -> list[schema.PreviewChannel]:
        """What each checked channel's values looked like (an import preview's table)."""
        out = []
        for c, seen in self._seen.items():
            out.append(
                schema.PreviewChannel(
                    channel=c,
                    unit=schema.CHANNELS[c].unit,
                    source=c,
                    count=seen.n,
                    min=None if seen.low > seen.high else seen.low,
                    max=None if seen.low > seen.high else seen.high,
                    plausible=schema.SENSOR_LIMITS[c],
                    outside=seen.outside,
                )
            )
        return out

    def refusal(self) -> tuple[str, str] | None:
        """``(channel, what is wrong)`` of the first value problem that refuses the file, else None."""
        for c, s in self._seen.items():
            if s.n and s.outside > OUTSIDE_REFUSED * s.n:
                lo, hi = schema.SENSOR_LIMITS[c]
                unit = schema.CHANNELS[c].unit
                return c, (
                    f"{s.outside} of its {s.n} values are outside the plausible range of {c} ({lo:g} to {hi:g} "
                    f"{unit}): is the column in {unit}?"
                )
            if c in _FOOT and s.n - s.outside >= _RADIANS_MIN_SAMPLES and s.high - s.low > FOOT_WALKING_SPAN_DEG:
                if s.high > -s.low:
                    return c, (
                        f"the foot angle reaches {s.high:+.0f} deg toes-up but only {s.low:+.0f} deg toes-down: in "
                        "walking the foot is steepest toes-down at toe-off (about -60 deg) and gaitscope's foot angle "
                        "is (+) toes up; is the column's sign reversed?"
                    )
            if s.n and s.hyperextended > 0.01 * s.n:
                return c, (
                    f"the knee hyperextends beyond {-KNEE_HYPEREXTENSION_DEG:g} deg in {s.hyperextended} of {s.n} "
                    "samples: gaitscope's knee angle is (+) in flexion; is the column's sign reversed?"
                )
        return None

    def warnings(self) -> list[str]:
        """What looks wrong but does not refuse the file, in the user's terms."""
        out = []
        for c, s in self._seen.items():
            if s.outside:
                lo, hi = schema.SENSOR_LIMITS[c]
                out.append(
                    f"{c}: {s.outside} of {s.n} values outside its plausible range ({lo:g} to {hi:g}), "
                    "treated as missing"
                )
            span = s.high - s.low
            if (
                c.endswith("_deg")
                and s.n - s.outside >= _RADIANS_MIN_SAMPLES
                and -math.pi <= s.low <= s.high <= math.pi
                and span < _RADIANS_SPAN_DEG
            ):
                out.append(
                    f"{c}: its values span {span:.2f} deg over {s.n} samples, within +/-pi: radians? "
                    "(fine if the subject stood still)"
                )
        return out
