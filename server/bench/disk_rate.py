"""How many bytes a second a live recording takes, for a few channel sets: ``python -m server.bench.disk_rate``.

Runs what a live session runs per frame, without a server: the estimator stack chosen for the channels
(:class:`~sessions.estimation.FrameEstimator`) and the recorder (:class:`~sessions.formats.recording.Recorder`,
the same chunking and compression), on cohort walking at 200 Hz. The walking channels carry the cohort's
signals; every other channel a device declares carries a smooth signal with sensor noise, at full float
precision, as real sensors give (a constant would compress to nothing and understate the rate). The
figures in :mod:`gaitscope.sessions.live.disk` and the disk section of ``docs/dashboard.md`` come from this.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Final

import numpy as np

from gaitscope.sessions import schema
from gaitscope.sessions.estimation import FrameEstimator, torque_json
from gaitscope.sessions.formats.models import default_model_path, load_model
from gaitscope.sessions.formats.recording import Recorder
from gaitscope.sessions.synth.trials import replay_input, sensor_trial

#: The channel sets measured: a shank and foot encoder device, one with shank and foot IMUs, and every channel.
WALKING: Final = ("foot_angle_deg", "foot_vel_dps", "shank_angle_deg", "shank_vel_dps", "heel_forward_m",
                  "heel_up_m", "foot_force_N")  # fmt: skip
IMUS: Final = WALKING + tuple(
    f"imu_{seg}_{kind}_{axis}_{unit}"
    for seg in ("shank", "foot")
    for kind, unit in (("gyro", "dps"), ("accel", "m_s2"))
    for axis in "xyz"
)
CHANNEL_SETS: Final = {"walking (7)": WALKING, "walking + 2 IMUs (19)": IMUS, "all": tuple(schema.SENSOR_LIMITS)}


@dataclass(frozen=True)
class DiskRate:
    """One measurement: ``channels`` sent at ``rate_hz`` for ``seconds`` of session time made ``bytes`` of MCAP."""

    channels: int
    estimators: tuple[str, ...]
    rate_hz: float
    seconds: float
    bytes: int

    @property
    def bytes_per_s(self) -> float:
        return self.bytes / self.seconds


def measure(
    channels: Sequence[str], rate_hz: float = 200.0, seconds: float = 60.0, *, declared: bool = True, seed: int = 0
) -> DiskRate:
    """The MCAP bytes a session sending ``channels`` at ``rate_hz`` records in ``seconds`` (index included);
    ``declared``: the device declares its channels (else the default stack runs, as for a device that does not)."""
    model, _ = load_model(default_model_path())
    sensors, _, _ = sensor_trial([(1.2, 0.0, math.ceil(seconds) + 2)], rate_hz=rate_hz)
    walk = replay_input(sensors)
    rng = np.random.default_rng(seed)
    n = round(seconds * rate_hz)
    estimator = FrameEstimator(
        model, 0.9, 75.0, schema.SessionSettings(), 1.0 / rate_hz, channels=list(channels) if declared else None
    )
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "rate.mcap"
        with Recorder(path, time.time_ns(), {}, channels=estimator.recorded_channels()) as recorder:
            for k in range(n):
                t = k / rate_hz
                values: dict[str, float] = {}
                for j, name in enumerate(channels):
                    if name in walk.signals:
                        values[name] = float(walk.signals[name][k])
                    else:
                        lo, hi = schema.SENSOR_LIMITS[name]
                        span = min(hi - lo, 200.0)
                        values[name] = float(span / 4 * math.sin(2 * math.pi * t + j) + rng.normal(0, span / 200))
                frame = schema.SensorFrame.model_validate({"seq": k, "t": t, **values})
                state = estimator.step(frame, time.time_ns())
                command = torque_json(k, t, state.torque_Nm).encode()
                recorder.write_json(t, estimator.recorded_json(frame, state, command))
        size = path.stat().st_size
    return DiskRate(len(channels), tuple(estimator.stack.names), rate_hz, seconds, size)


def main(argv: Sequence[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=60.0, help="session time recorded per channel set")
    p.add_argument("--rate", type=float, default=200.0, help="frames per second")
    a = p.parse_args(argv)
    print(f"{'channels':>24} {'estimators':>10} {'kB/s':>7} {'MiB/hour':>9}  minutes per 100 MiB")
    runs = [(name, channels, True) for name, channels in CHANNEL_SETS.items()]
    runs.insert(1, ("walking, not declared", WALKING, False))
    for name, channels, declared in runs:
        r = measure(channels, a.rate, a.seconds, declared=declared)
        print(f"{name:>24} {len(r.estimators):>10} {r.bytes_per_s / 1000:>7.1f} {r.bytes_per_s * 3600 / 2**20:>9.0f}"
              f"  {100 * 2**20 / r.bytes_per_s / 60:.1f}  ({', '.join(r.estimators)})")  # fmt: skip


if __name__ == "__main__":
    main()
