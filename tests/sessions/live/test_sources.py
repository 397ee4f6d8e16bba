"""Frame sources: tables to frames (a version 1 replay CSV, the simulated device's every channel)."""

from __future__ import annotations

import asyncio
import json
import math
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from pydantic import ValidationError

from gaitscope.sessions import schema
from gaitscope.sessions.formats.replay_io import read_replay_csv
from gaitscope.sessions.live.sources import (
    CONNECT_S,
    RECEIVE_S,
    DeviceBudget,
    FrameTable,
    LiveDevice,
    SimulatedDevice,
    frame_refusal,
    frames_from_table,
    invalid_notice,
)
from gaitscope.sessions.synth.trials import replay_columns, sensor_trial

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


# --- a live device's share of the event loop, and the frames refused unparsed (issue 21) ----------------


class Clock:
    """Monotonic seconds that move only when told."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_a_device_within_its_share_reads_on_and_hands_the_loop_back_every_slice() -> None:
    clock = Clock()
    budget = DeviceBudget(share=0.25, burst_s=1.0, slice_s=0.001, clock=clock)
    pauses = []
    for _ in range(200):  # 200 frames of 0.4 ms a second: 8 % of the loop
        clock.now += 0.005
        budget.charge(0.0004)
        pauses.append(budget.pause())
    assert set(pauses) == {None, 0.0}
    assert pauses.count(0.0) == 200 // 3  # a turn after every 1 ms of work: every third frame
    assert budget.used == pytest.approx(0.08) and not budget.exhausted


def test_a_device_over_its_share_waits_until_it_has_earned_it_back() -> None:
    clock = Clock()
    budget = DeviceBudget(share=0.25, burst_s=1.0, clock=clock)
    budget.charge(0.25)  # the whole burst: the credit is spent, not owed
    assert budget.pause() == 0.0  # a turn (past the slice), no wait
    budget.charge(0.05)
    assert budget.pause() == pytest.approx(0.2)  # 50 ms of work at 25 %: 200 ms held back
    clock.now += 0.1
    assert budget.pause() == pytest.approx(0.1)
    clock.now += 0.1
    assert budget.pause() is None
    clock.now += 100.0
    budget.charge(0.2)
    assert budget.pause() == 0.0  # the credit refilled to the burst only (0.25 s), not 100 s worth


def test_only_a_device_held_back_for_seconds_mostly_for_refused_messages_is_exhausted() -> None:
    def run(refused: bool) -> DeviceBudget:
        clock = Clock()
        budget = DeviceBudget(share=0.25, burst_s=1.0, close_after_s=5.0, clock=clock)
        for _ in range(7_000):  # 1 ms of work per ms of time: four times its share, for 7 s
            budget.charge(0.001, refused=refused)
            if budget.exhausted:
                break
            clock.now += 0.001 + (budget.pause() or 0.0)  # the handler waits as told
        budget.clock_s = clock.now  # type: ignore[attr-defined]
        return budget

    flood = run(refused=True)
    # held back once its 0.25 s burst is spent (1 ms of work a ms, 0.25 ms earned back: at 1/3 s), then 5 s
    assert flood.exhausted and flood.clock_s == pytest.approx(1 / 3 + 5.0, abs=0.01)  # type: ignore[attr-defined]
    assert flood.used / flood.clock_s == pytest.approx(0.25, abs=0.05)  # type: ignore[attr-defined]
    costly = run(refused=False)  # valid frames that cost a lot: held to its share, never disconnected for it
    assert not costly.exhausted and costly.used / costly.clock_s == pytest.approx(0.25, abs=0.05)  # type: ignore[attr-defined]


def test_a_break_within_its_share_starts_the_count_again() -> None:
    clock = Clock()
    budget = DeviceBudget(share=0.1, burst_s=1.0, close_after_s=5.0, clock=clock)
    budget.charge(0.2, refused=True)
    assert budget.pause() == pytest.approx(1.0)
    clock.now += 4.9
    budget.charge(0.001, refused=True)  # within its credit again: not held back any more
    clock.now += 0.2
    assert budget.pause() == 0.0 and not budget.exhausted  # a turn, no wait


def test_a_budget_refuses_nonsense() -> None:
    for share in (0.0, -0.1, 1.5):
        with pytest.raises(ValueError, match="share"):
            DeviceBudget(share=share)


def test_a_device_s_share_follows_its_declared_rate_within_bounds() -> None:
    assert LiveDevice(200.0).budget.share == pytest.approx(0.25)  # 250 frames/s of 1 ms
    assert LiveDevice(1000.0).budget.share == 0.5
    assert LiveDevice(1.0).budget.share == 0.05
    assert 0 < RECEIVE_S < CONNECT_S < 0.01


def test_a_frame_too_long_or_of_too_many_keys_is_refused_unparsed_with_its_size_and_the_limit() -> None:
    good = json.dumps({"type": "frame", "seq": 1, "t": 0.0, **dict.fromkeys(schema.CHANNELS, 1.0)})
    assert frame_refusal(good) is None
    long = '{"type": "frame", "seq": 1, "t": 0.0, "foot_angle_deg": ' + " " * schema.MAX_FRAME_BYTES + "1}"
    notice = frame_refusal(long)
    assert notice is not None and notice.kind == "too_large"
    assert f"{len(long)} characters, over the limit of {schema.MAX_FRAME_BYTES}" in str(notice.detail)
    keys = json.dumps({"type": "frame", "seq": 1, "t": 0.0, **{f"x{i}": 0 for i in range(500_000)}})  # 6.9 MB
    start = time.perf_counter()
    notice = frame_refusal(keys)
    assert time.perf_counter() - start < 0.05  # was 14-20 s of validation
    assert notice is not None and notice.kind == "too_large" and len(notice.model_dump_json()) < 200
    few_keys = json.dumps({"type": "frame", "seq": 1, "t": 0.0, **{f"x{i}": 0 for i in range(100)}})  # 1.4 kB
    notice = frame_refusal(few_keys)
    assert (
        notice is not None
        and notice.kind == "too_large"
        and f"103 keys, more than a frame's {schema.MAX_FRAME_KEYS}" in str(notice.detail)
    )


def test_an_invalid_notice_lists_a_few_errors_and_counts_them_without_the_input() -> None:
    name = "k" * 5000
    text = json.dumps({"type": "frame", "seq": -1, "t": "soon", name: 1, **{f"x{i}": 0 for i in range(60)}})
    assert frame_refusal(text) is None  # short enough, few enough keys: validated
    with pytest.raises(ValidationError) as e:
        schema.SensorFrame.model_validate_json(text)
    notice = invalid_notice(e.value)
    assert notice.kind == "invalid" and notice.errors == 63  # seq, t, the long key, 60 unknown keys
    assert isinstance(notice.detail, list) and len(notice.detail) == schema.MAX_NOTICE_ERRORS
    assert notice.detail[0] == {
        "loc": ["seq"],
        "msg": "Input should be greater than or equal to 0",
        "type": "greater_than_equal",
    }
    reply = notice.model_dump_json()
    assert len(reply) < 1000 and "soon" not in reply and "k" * 41 not in reply  # never the input
