"""Frame sources: tables to frames (a version 1 replay CSV, the simulated device's every channel)."""

from __future__ import annotations

import asyncio
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sessions import schema
from sessions.formats.replay_io import read_replay_csv
from sessions.live.sources import FrameTable, SimulatedDevice, frames_from_table
from sessions.synth.trials import replay_columns, sensor_trial

V1_CHANNELS = {*schema.REPLAY_SIGNALS, "heel_strike"}


@pytest.fixture(scope="module")
def sensors() -> pd.DataFrame:
    return sensor_trial([(1.0, 0.0, 6)], rate_hz=100.0)[0]


def test_a_version_1_replay_csv_still_gives_frames(sensors: pd.DataFrame, tmp_path: Path) -> None:
    path = tmp_path / "walk.csv"
    replay_columns(sensors).to_csv(path, index=False)  # the replay CSV as version 1 wrote it
    trial = read_replay_csv(path)
    assert set(trial.signals) == set(schema.REPLAY_SIGNALS) and trial.heel_strike is not None
    frames = frames_from_table(pd.read_csv(path))
    assert len(frames) == len(sensors) and all(f.version == 2 for f in frames)
    for k in (0, 17, len(frames) - 1):
        f = frames[k]
        assert {n for n in schema.CHANNELS if getattr(f, n) is not None} == V1_CHANNELS
        assert f.seq == k and f.t == pytest.approx(trial.time_s[k])
        assert f.foot_angle_deg == pytest.approx(trial.signals["foot_angle_deg"][k], abs=1e-9)
        assert f.heel_strike == bool(trial.heel_strike[k])
    assert "hip_angle_deg" in schema.missing_channels(schema.CHANNELS, frames[0])


def test_the_simulated_trial_carries_every_channel_within_its_limits(sensors: pd.DataFrame) -> None:
    frames = frames_from_table(sensors)
    assert len(frames) == len(sensors)
    for f in frames[:: len(frames) // 25]:
        assert schema.missing_channels(schema.CHANNELS, f) == []
        assert f.plausible() == (f, 0)
    contact = np.array([f.foot_contact for f in frames])
    assert contact.dtype == bool and 0.5 < contact.mean() < 0.75  # stance is about 60 % of the cycle


def test_a_frame_table_skips_non_finite_cells_and_reads_flags() -> None:
    table = pd.DataFrame(
        {
            "time_s": [0.0, 0.01],
            "foot_angle_deg": [1.0, math.nan],
            "foot_contact": [1, 0],
            "heel_strike": [0.0, 1.0],
            "not_a_channel": [5.0, 6.0],
        }
    )
    rows = FrameTable(table)
    first, second = rows.frame(0), rows.frame(1)
    assert (first.foot_angle_deg, first.foot_contact, first.heel_strike) == (1.0, True, False)
    assert (second.foot_angle_deg, second.foot_contact, second.heel_strike) == (None, False, True)


def test_the_simulated_device_sends_every_channel() -> None:
    spec = schema.SimulatedSource(protocol=[schema.ProtocolStep(speed_m_s=1.2, incline_deg=5.0, strides=3)])

    async def take(n: int) -> list[schema.SensorFrame]:
        out: list[schema.SensorFrame] = []
        async for f in SimulatedDevice(spec).frames():
            out.append(f)
            if len(out) == n:
                break
        return out

    frames = asyncio.run(take(20))
    assert [f.seq for f in frames] == list(range(20)) and all(f.version == 2 for f in frames)
    for f in frames:
        assert schema.missing_channels(schema.CHANNELS, f) == [] and f.plausible()[1] == 0
        assert f.belt_speed_m_s == 1.2
