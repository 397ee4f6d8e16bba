"""A subject's gait fingerprint from a recorded walk (seed 004's least-squares fingerprint, LS-GF).

Seed 004 fed its LS-GF the ground truth. A clinic has none, so a calibration walk supplies it the way a
gait lab would: strides run from heel strike to heel strike (the recorded ones, else those the stack
detected), phase is linear in time within a stride, and stride length is the belt speed times the stride
time when the trial records the belt (a treadmill), else the stride length the recorded primary estimator
gave (its mean over the stride). Strides that cannot serve are left out, each with its reason:

- a stride time outside ``[MIN_STRIDE_S, MAX_STRIDE_S]`` (a missed or double heel strike);
- a thigh angle missing (dropout, NaN) anywhere in the stride, or a gap of more than ``MAX_GAP_S``;
- less than ``MIN_THIGH_RANGE_DEG`` of thigh motion (standing, shuffling).

With fewer than ``MIN_STRIDES`` strides left the calibration is refused, saying why; nothing is stored.
"""

from __future__ import annotations

import itertools
import math
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

import numpy as np

from gaitscope.estimators.fingerprint import FingerprintMap, basis
from gaitscope.sessions.formats.mcap_io import read_messages

__all__ = ["MIN_STRIDES", "Calibration", "CalibrationRefused", "CalibrationWalk", "calibrate", "read_walk"]

#: Fewest usable strides a calibration takes (about 10 s of walking): a choice, see docs/dashboard.md.
MIN_STRIDES: Final = 8
MIN_STRIDE_S: Final = 0.4
MAX_STRIDE_S: Final = 4.0
MAX_GAP_S: Final = 0.1
MIN_THIGH_RANGE_DEG: Final = 10.0


class CalibrationRefused(ValueError):
    """A walk that cannot calibrate a fingerprint; the message says why and what would do."""


@dataclass(frozen=True)
class CalibrationWalk:
    """What a calibration reads of a trial, one entry per sample (NaN: missing)."""

    t: np.ndarray
    thigh_deg: np.ndarray
    heel_strike: np.ndarray  # bool
    belt_m_s: np.ndarray
    stride_estimate_m: np.ndarray
    estimator: str = "the recorded estimate"


@dataclass(frozen=True)
class Calibration:
    """A fitted fingerprint and what it was fitted from."""

    fingerprint: np.ndarray
    fit_rmse_avg_deg: float
    fit_rmse_personal_deg: float
    strides_used: int
    seconds_used: float
    excluded: dict[str, int] = field(default_factory=dict)
    stride_length_source: str = "belt speed"

    @property
    def strides_excluded(self) -> int:
        return sum(self.excluded.values())


def read_walk(path: Path) -> CalibrationWalk:
    """The thigh angle, heel strikes, belt speed and estimated stride length of a gaitscope recording.

    Raises:
        DataFormatError: a bad file.
        CalibrationRefused: the trial has no thigh angle or no samples.
    """
    frames: dict[int, dict[str, object]] = {}
    states: dict[int, dict[str, object]] = {}
    for topic, _, msg in read_messages(path, ["/sensor", "/gait_state"]):
        (frames if topic == "/sensor" else states)[int(msg["seq"])] = msg
    seqs = sorted(set(frames) & set(states))
    if not seqs:
        raise CalibrationRefused("the trial holds no estimated samples to calibrate from")

    def col(rows: dict[int, dict[str, object]], key: str) -> np.ndarray:
        return np.array([_num(rows[s].get(key)) for s in seqs])

    thigh = col(frames, "thigh_angle_deg")
    if not np.isfinite(thigh).any():
        raise CalibrationRefused(
            "the trial has no thigh angle: the fingerprint model is of the thigh (record a walk with a thigh sensor)"
        )
    recorded_hs = [frames[s].get("heel_strike") for s in seqs]
    hs = (
        np.array([bool(v) for v in recorded_hs])
        if any(v is not None for v in recorded_hs)
        else np.array([bool(states[s].get("heel_strike")) for s in seqs])
    )
    return CalibrationWalk(
        t=col(states, "t"),
        thigh_deg=thigh,
        heel_strike=hs,
        belt_m_s=col(frames, "belt_speed_m_s"),
        stride_estimate_m=col(states, "stride_length_m"),
    )


def _num(v: object) -> float:
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else math.nan


def calibrate(fmap: FingerprintMap, walk: CalibrationWalk, min_strides: int = MIN_STRIDES) -> Calibration:
    """The least-squares fingerprint of ``walk`` in ``fmap`` (seed 004 eqs. 36-40) from its usable strides.

    Raises:
        CalibrationRefused: no heel strikes, or fewer than ``min_strides`` usable strides (the message counts
            the strides left out by reason).
    """
    idx = np.flatnonzero(walk.heel_strike)
    if idx.size < 2:
        raise CalibrationRefused(
            "no strides: the trial has fewer than two heel strikes "
            "(was the subject walking? are the foot signals there?)"
        )
    excluded: Counter[str] = Counter()
    parts_p, parts_l, parts_th = [], [], []
    belt_used = 0
    seconds = 0.0
    for i0, i1 in itertools.pairwise(idx):
        t, th = walk.t[i0:i1], walk.thigh_deg[i0:i1]
        T = float(walk.t[i1] - walk.t[i0])
        if not MIN_STRIDE_S <= T <= MAX_STRIDE_S:
            excluded[f"stride time outside {MIN_STRIDE_S:g}-{MAX_STRIDE_S:g} s"] += 1
            continue
        if not np.isfinite(th).all():
            excluded["thigh angle missing"] += 1
            continue
        if np.diff(walk.t[i0 : i1 + 1]).max() > MAX_GAP_S:
            excluded[f"a gap of over {MAX_GAP_S:g} s"] += 1
            continue
        if np.ptp(th) < MIN_THIGH_RANGE_DEG:
            excluded[f"under {MIN_THIGH_RANGE_DEG:g} deg of thigh motion (standing?)"] += 1
            continue
        belt = walk.belt_m_s[i0:i1]
        if np.isfinite(belt).all() and belt.mean() > 0.1:
            length = float(belt.mean()) * T
            belt_used += 1
        else:
            est = walk.stride_estimate_m[i0:i1]
            if not np.isfinite(est).any():
                excluded["no stride length (no belt speed, no estimate)"] += 1
                continue
            length = float(np.nanmean(est))
        parts_p.append((t - t[0]) / T)
        parts_l.append(np.full(t.size, length))
        parts_th.append(th)
        seconds += T
    used = len(parts_p)
    if used < min_strides:
        why = "; ".join(f"{n} {reason}" for reason, n in excluded.most_common()) or "none left out"
        raise CalibrationRefused(
            f"only {used} usable strides of {idx.size - 1} (left out: {why}); "
            f"walk at least {min_strides} steady strides"
        )
    p, l, th = np.concatenate(parts_p), np.concatenate(parts_l), np.concatenate(parts_th)
    g = fmap.ls_fingerprint(p, l, th)
    A = basis(p, l, fmap.order)
    source = "belt speed" if belt_used == used else ("belt speed and " if belt_used else "") + walk.estimator
    return Calibration(
        fingerprint=g,
        fit_rmse_avg_deg=float(np.sqrt(np.mean((A @ fmap.xi_avg - th) ** 2))),
        fit_rmse_personal_deg=float(np.sqrt(np.mean((A @ fmap.xi(g) - th) ** 2))),
        strides_used=used,
        seconds_used=seconds,
        excluded=dict(excluded),
        stride_length_source=source,
    )
