"""``gaitscope replay`` end to end: the golden trial, batch against streaming, output written in parts.

The golden files in ``tests/data/golden/`` are a 20 s, 100 Hz trial of the virtual cohort (subject
VC01; how it was made: ``tests/data/golden/README.md``) and its replay output. A change of any replayed
number beyond 1e-9 fails here, so that it is seen in review and the output regenerated deliberately.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from gaitscope.estimators.pipeline import GaitStatePipeline, PipelineConfig
from gaitscope.server.cli import main
from gaitscope.sessions import schema
from gaitscope.sessions.formats.models import default_model_path, load_model
from gaitscope.sessions.offline import replay

GOLDEN = Path(__file__).parents[2] / "data" / "golden"
TRIAL, EXPECTED = GOLDEN / "trial_20s.csv", GOLDEN / "trial_20s_replay.csv"
SUBJECT = ["--leg-length", "0.8778", "--mass", "64.37"]  # VC01 of the default cohort
ROOT = GOLDEN.parents[2]
REGENERATE = f"gaitscope replay {TRIAL.relative_to(ROOT)} --out {EXPECTED.relative_to(ROOT)} {' '.join(SUBJECT)}"
TOL = 1e-9


def test_replay_of_the_golden_trial_matches_the_committed_output(tmp_path: Path) -> None:
    out = tmp_path / "replay.csv"
    assert main(["replay", str(TRIAL), "--out", str(out), *SUBJECT]) == 0
    got, expected = pd.read_csv(out), pd.read_csv(EXPECTED)
    assert list(got.columns) == list(expected.columns) == list(schema.REPLAY_OUTPUT)
    assert len(got) == len(expected) == 2000
    for column in schema.REPLAY_OUTPUT:
        a, b = got[column].to_numpy(float).tolist(), expected[column].to_numpy(float).tolist()
        diff = np.abs(np.subtract(a, b))
        worst = int(np.argmax(diff))
        assert diff[worst] <= TOL, (
            f"replay output column {column!r} differs from the golden output by {diff[worst]:.3g} at row "
            f"{worst + 2} ({a[worst]!r} instead of {b[worst]!r}). If the change is intended, regenerate the "
            f"golden output from the repository root with\n    {REGENERATE}\n"
            "and commit it together with the change that caused it."
        )


def test_batch_and_streaming_replays_write_the_same_bytes(tmp_path: Path) -> None:
    model, _ = load_model(default_model_path())
    config = PipelineConfig(leg_length=0.8778, body_mass_kg=64.37)
    batch, stream = tmp_path / "batch.csv", tmp_path / "stream.csv"
    fast = replay.replay_file(TRIAL, batch, model, config)
    slow = replay.replay_file(TRIAL, stream, model, config, batch=False)
    assert replace(fast, wall_s=0.0) == replace(slow, wall_s=0.0) and fast.heel_strikes == 18
    assert batch.read_bytes() == stream.read_bytes()


def test_parts_join_seamlessly(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    model, _ = load_model(default_model_path())
    config = PipelineConfig(leg_length=0.8778, body_mass_kg=64.37)
    whole, parts = tmp_path / "whole.csv", tmp_path / "parts.csv"
    replay.replay_file(TRIAL, whole, model, config)
    monkeypatch.setattr(replay, "PART", 333)  # parts cut strides, heel strikes and the filters' state
    replay.replay_file(TRIAL, parts, model, config)
    assert parts.read_bytes() == whole.read_bytes()


def test_a_failure_during_the_replay_leaves_no_output(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    model, _ = load_model(default_model_path())
    out = tmp_path / "out.csv"
    out.write_text("an older output\n")
    calls = []

    def fail_on_the_third_part(self: GaitStatePipeline, *args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        if len(calls) == 3:
            raise RuntimeError("estimator fault")
        return original(self, *args, **kwargs)

    original = GaitStatePipeline.run
    monkeypatch.setattr(replay, "PART", 500)
    monkeypatch.setattr(GaitStatePipeline, "run", fail_on_the_third_part)
    with pytest.raises(RuntimeError, match="estimator fault"):
        replay.replay_file(TRIAL, out, model, PipelineConfig())
    assert out.read_text() == "an older output\n"
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]


def test_a_replay_runs_the_filter_as_a_live_session_does_unless_as_published(tmp_path: Path) -> None:
    from gaitscope.sessions.synth.cohort import CohortSpec, make_subjects
    from gaitscope.sessions.synth.real_walks import RealWalkSpec, real_walk

    subject = make_subjects(CohortSpec())[0]
    walk = real_walk(subject, RealWalkSpec(bouts=2, dropouts_per_min=0.0))
    trial = tmp_path / "walk.csv"
    shank_only = [schema.REPLAY_TIME, "shank_angle_deg", "shank_vel_dps"]
    walk[shank_only].to_csv(trial, index=False)
    model, _ = load_model(default_model_path())
    config = PipelineConfig(leg_length=subject.leg_length_m, body_mass_kg=subject.mass_kg)
    live, paper = tmp_path / "live.csv", tmp_path / "paper.csv"
    summary = replay.replay_file(trial, live, model, config, supervised=True)
    published = replay.replay_file(trial, paper, model, config)
    out, out_paper = pd.read_csv(live), pd.read_csv(paper)
    still = (walk["condition"] == "standing").to_numpy()
    settled = still & np.r_[still[100:], np.zeros(100, bool)] & np.r_[np.zeros(150, bool), still[:-150]]
    # standing: phase held, rate 0, no torque; the filter as published runs on and pushes
    assert summary.supervised and summary.standing_s > 5.0 and not published.supervised
    assert (out.loc[settled, "phase_rate"] == 0).all() and (out.loc[settled, "torque_Nm"] == 0).all()
    assert out_paper.loc[settled, "torque_Nm"].max() > 1.0
    # shank only: heel strikes from the shank, so the walking phase follows the truth
    walking = ~still
    err = np.abs((out["phase"] - walk["gt_phase"] + 0.5) % 1.0 - 0.5)[walking]
    err_paper = np.abs((out_paper["phase"] - walk["gt_phase"] + 0.5) % 1.0 - 0.5)[walking]
    assert summary.heel_strikes > 20 and published.heel_strikes == 0
    assert np.sqrt(np.mean(err**2)) < 0.08 < np.sqrt(np.mean(err_paper**2))
    assert np.isfinite(out["torque_Nm"]).all() and out["torque_Nm"].between(0, config.max_torque).all()
    assert "standing still" in "\n".join(summary.lines())


def test_a_replay_is_what_a_live_session_makes_of_the_same_frames(tmp_path: Path) -> None:
    """One sensor-to-torque path: the golden trial's frames through a live session's frame estimator (its
    stack of phase_ekf and tbe, without the soft start, which ramps a person's assistance) give the replay's
    every number, the torque included."""
    from gaitscope.sessions.estimation import FrameEstimator
    from gaitscope.sessions.formats.replay_io import read_replay_csv

    model, _ = load_model(default_model_path())
    data = read_replay_csv(TRIAL)
    assert data.heel_strike is not None
    settings = schema.SessionSettings(estimators=["phase_ekf", "tbe"], primary="phase_ekf", max_torque_Nm=40.0)
    live = FrameEstimator(model, 0.8778, 64.37, settings, 0.01, time_origin=0.0, soft_start=False)
    states = []
    for k, t in enumerate(data.time_s.tolist()):
        values = {name: float(v[k]) for name, v in data.signals.items()}
        frame = schema.SensorFrame(seq=k, t=t, heel_strike=bool(data.heel_strike[k]), **values)
        states.append(live.step(frame, 0))
    out = tmp_path / "replay.csv"
    replay.replay_file(TRIAL, out, model, PipelineConfig(leg_length=0.8778, body_mass_kg=64.37), supervised=True)
    got = pd.read_csv(out)
    for column in schema.REPLAY_OUTPUT[1:]:
        expected = np.array([float(getattr(s, column)) for s in states])
        assert np.abs(got[column].to_numpy(float) - expected).max() <= TOL, column
    assert got["torque_Nm"].max() > 10.0 and got["heel_strike"].sum() == 18


def _real_walk_files(tmp_path: Path) -> list[Path]:
    """The golden trial (heel strikes given); a real walk (starts, stops, standing) with every channel and no heel
    strikes, dropouts written as values out of range (a replay file has no NaN cells); and its shank only."""
    from gaitscope.sessions.synth.cohort import CohortSpec, make_subjects
    from gaitscope.sessions.synth.real_walks import RealWalkSpec, real_walk

    walk = real_walk(make_subjects(CohortSpec())[0], RealWalkSpec(bouts=2, dropouts_per_min=0.0))
    rng = np.random.default_rng(24)
    for _ in range(30):
        a, column = int(rng.integers(0, len(walk) - 40)), str(rng.choice(schema.REPLAY_SIGNALS))
        walk.loc[a : a + int(rng.integers(1, 40)), column] = 9999.0
    every, shank = tmp_path / "walk.csv", tmp_path / "shank.csv"
    walk[[schema.REPLAY_TIME, *schema.REPLAY_SIGNALS]].to_csv(every, index=False)
    walk[[schema.REPLAY_TIME, "shank_angle_deg", "shank_vel_dps"]].to_csv(shank, index=False)
    return [TRIAL, every, shank]


def test_supervised_compiled_and_stepped_replays_write_the_same_bytes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    model, _ = load_model(default_model_path())
    config = PipelineConfig(leg_length=0.8778, body_mass_kg=64.37)
    for trial in _real_walk_files(tmp_path):
        fast, slow, cut = tmp_path / "fast.csv", tmp_path / "slow.csv", tmp_path / "cut.csv"
        a = replay.replay_file(trial, fast, model, config, supervised=True)
        b = replay.replay_file(trial, slow, model, config, supervised=True, batch=False)
        assert replace(a, wall_s=0.0) == replace(b, wall_s=0.0), trial.name
        assert fast.read_bytes() == slow.read_bytes(), trial.name
        if trial != TRIAL:
            assert a.standing_s > 3.0 and a.heel_strikes > 20 and a.heel_strikes_detected
        with monkeypatch.context() as m:
            m.setattr(replay, "PART", 333)
            replay.replay_file(trial, cut, model, config, supervised=True)
        assert cut.read_bytes() == fast.read_bytes(), trial.name


def test_a_supervised_replay_steps_the_stack_from_where_it_would_fail(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Where the stack marks an estimator failed, the compiled path hands over to stepping, which reports it."""
    model, _ = load_model(default_model_path())
    config = PipelineConfig(leg_length=0.8778, body_mass_kg=64.37)
    built = replay.replay_stack

    def strict(*args: Any, **kwargs: Any) -> Any:
        stack = built(*args, **kwargs)
        stack.max_variance = 2e-3  # a covariance bound the filter's own health limit lets through
        return stack

    monkeypatch.setattr(replay, "replay_stack", strict)
    monkeypatch.setattr(replay, "PART", 10)  # the stack fails the filter at sample 29
    fast, slow = tmp_path / "fast.csv", tmp_path / "slow.csv"
    handed: list[int] = []
    original = replay._Stacked.estimate

    def spy(self: Any, out: Any, a: int, b: int) -> int:
        handed.append(a)
        return original(self, out, a, b)

    monkeypatch.setattr(replay._Stacked, "estimate", spy)
    a = replay.replay_file(TRIAL, fast, model, config, supervised=True)
    assert handed[:3] == [0, 20, 30]  # compiled for two parts; the trial's start stepped again, then the rest
    b = replay.replay_file(TRIAL, slow, model, config, supervised=True, batch=False)
    assert any("failed" in e for e in a.events)
    assert repr(replace(a, wall_s=0.0)) == repr(replace(b, wall_s=0.0))  # (NaN means: not estimated)
    assert fast.read_bytes() == slow.read_bytes()


def test_the_replay_lists_the_columns_it_ignored_and_what_the_file_cannot_feed(tmp_path: Path) -> None:
    """Issue #25: every channel column is read, the others listed back; the registry says what the file's
    channels cannot feed."""
    model, _ = load_model(default_model_path())
    src = tmp_path / "lab.csv"
    t = np.arange(300) * 0.01
    pd.DataFrame({"time_s": t, "shank_angle_deg": 20 * np.sin(2 * np.pi * t), "Notes": "x"}).to_csv(src, index=False)
    summary = replay.replay_file(src, tmp_path / "out.csv", model, PipelineConfig(), supervised=True)
    assert summary.ignored == ("Notes",) and summary.channels == ("shank_angle_deg",)
    assert (
        "fp_avg needs thigh_angle_deg" in summary.cannot_feed
        and "gp_ekf needs hip_angle_deg, knee_angle_deg, ankle_angle_deg" in summary.cannot_feed
    )
    assert not any(c.startswith(("phase_ekf", "tbe", "imu_")) for c in summary.cannot_feed)
    assert "ignored          Notes (not channels)" in summary.lines()
