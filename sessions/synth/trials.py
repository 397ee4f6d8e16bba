"""Ready-made trials from the virtual cohort: the default replay trial and benchmark trials.

The default trial walks the treadmill protocol of seed 000 III-E: 1.2, 0.8, 1.2 and 0.8 m/s on the
level, then inclining in 2.5 deg steps to +10 deg and declining to -10 deg at 1.0 m/s. It is generated
deterministically (same bytes on every machine with the same library versions), so it ships as code
rather than as a multi-megabyte file.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from gaitscope.sessions import schema
from gaitscope.sessions.formats.replay_io import ReplayInput
from gaitscope.sessions.schema import TREADMILL_PROTOCOL
from gaitscope.sessions.synth.cohort import (
    CohortSpec,
    SensorNoise,
    generate_walk,
    make_subjects,
    resample_walk,
    simulate_sensors,
)

DEFAULT_SUBJECT = 0
DEFAULT_RATE_HZ = 100.0
DEFAULT_SEED = 7


__all__ = ["TREADMILL_PROTOCOL", "minutes_schedule", "replay_columns", "replay_input", "sensor_trial"]


def sensor_trial(
    schedule: Sequence[tuple[float, float, int]] = TREADMILL_PROTOCOL,
    subject: int = DEFAULT_SUBJECT,
    rate_hz: float = DEFAULT_RATE_HZ,
    seed: int = DEFAULT_SEED,
    noise: SensorNoise | None = None,
) -> tuple[pd.DataFrame, float, float]:
    """Simulated sensor recording of one cohort subject walking ``schedule``.

    Returns:
        The sensor frame (replay-CSV columns plus ``gt_*`` ground truth), the subject's leg length (m)
        and mass (kg).
    """
    subj = make_subjects(CohortSpec())[subject]
    rng = np.random.default_rng(seed)
    walk = generate_walk(subj, schedule, rng)
    uniform = resample_walk(walk, rate_hz)
    sensors = simulate_sensors(uniform, noise or SensorNoise(), rng)
    return sensors, subj.leg_length_m, subj.mass_kg


def replay_input(sensors: pd.DataFrame) -> ReplayInput:
    """A simulated sensor frame as the replay reader would return it (every channel, true heel strikes)."""
    return ReplayInput(
        time_s=sensors[schema.REPLAY_TIME].to_numpy(np.float64),
        signals={k: sensors[k].to_numpy(np.float64) for k in schema.REPLAY_SIGNALS},
        heel_strike=sensors[schema.REPLAY_HEEL_STRIKE].to_numpy() > 0.5,
    )


def replay_columns(sensors: pd.DataFrame) -> pd.DataFrame:
    """Only the columns of the replay CSV, in their documented order."""
    cols = [schema.REPLAY_TIME, *schema.REPLAY_SIGNALS, schema.REPLAY_HEEL_STRIKE]
    out = sensors[cols].copy()
    out[schema.REPLAY_HEEL_STRIKE] = out[schema.REPLAY_HEEL_STRIKE].astype(int)
    return out


def minutes_schedule(minutes: float, speed: float = 1.2, incline: float = 0.0) -> list[tuple[float, float, int]]:
    """A schedule of about ``minutes`` of walking at one condition (about 1.1 s per stride)."""
    return [(speed, incline, int(np.ceil(minutes * 60 / 1.0)))]
