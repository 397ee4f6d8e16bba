"""``gaitscope replay --estimators``: any stack of registered estimators on a file, each output a column.

Trials are the virtual cohort's (:func:`~gaitscope.sessions.synth.trials.sensor_trial`), with every channel the
simulation gives (thigh, joint, contralateral, IMU, force, contact flags, centre of mass); the inputs are built as
:func:`~gaitscope.sessions.formats.replay_io.read_replay_csv` returns them, so the tests do not depend on which
columns the reader keeps.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from gaitscope.estimators.pipeline import PipelineConfig, TrainedModel
from gaitscope.server.cli import main
from gaitscope.sessions import schema
from gaitscope.sessions.estimation import FrameEstimator
from gaitscope.sessions.formats.models import default_model_path, load_model
from gaitscope.sessions.formats.replay_io import ReplayInput
from gaitscope.sessions.offline import replay, replay_stack
from gaitscope.sessions.offline.replay_stack import replay_estimators, replay_input_estimators
from gaitscope.sessions.registry import DECLARED, ESTIMATORS, MissingChannels
from gaitscope.sessions.synth.trials import minutes_schedule, replay_columns, sensor_trial

GOLDEN = Path(__file__).parents[2] / "data" / "golden" / "trial_20s.csv"
SUBJECT = ["--leg-length", "0.8778", "--mass", "64.37"]  # VC01 of the default cohort, as the golden trial's
THIGH = ["thigh_angle_deg", "thigh_vel_dps"]
STACK = ["phase_ekf", "tbe", "fp_avg", "fp_gf"]


@pytest.fixture(scope="module")
def model() -> TrainedModel:
    return load_model(default_model_path())[0]


@pytest.fixture(scope="module")
def trial() -> tuple[pd.DataFrame, PipelineConfig]:
    """About 19 s of level walking at 1.2 m/s (VC01, 100 Hz), every simulated channel."""
    sensors, leg, mass = sensor_trial(minutes_schedule(0.3))
    return sensors, PipelineConfig(leg_length=leg, body_mass_kg=mass)


def _input(sensors: pd.DataFrame, columns: Sequence[str] | None = None) -> ReplayInput:
    """The trial as the replay reader returns it: ``columns`` (default: every channel of the simulation) as
    signals, flags as 0/1 floats, heel strikes apart."""
    keep = [c for c in (columns or sensors.columns) if c in schema.CHANNELS and c != schema.REPLAY_HEEL_STRIKE]
    return ReplayInput(
        time_s=sensors[schema.REPLAY_TIME].to_numpy(np.float64),
        signals={c: sensors[c].to_numpy(np.float64) for c in keep},
        heel_strike=sensors[schema.REPLAY_HEEL_STRIKE].to_numpy() > 0.5,
    )


def _exact(path: Path) -> dict[str, np.ndarray]:
    """A written CSV's columns, every cell parsed by ``float`` (the exact value of its shortest repr)."""
    with path.open(newline="") as file:
        header, *rows = csv.reader(file)
    return {c: np.array([float(r[j]) for r in rows]) for j, c in enumerate(header)}


def _frames(data: ReplayInput) -> list[schema.SensorFrame]:
    frames = []
    for k, t in enumerate(data.time_s.tolist()):
        values: dict[str, float | bool] = {c: float(v[k]) for c, v in data.signals.items()}
        for c in values:
            if schema.CHANNELS[c].unit == "bool":
                values[c] = values[c] == 1.0
        hs = None if data.heel_strike is None else bool(data.heel_strike[k])
        frames.append(schema.SensorFrame(seq=k, t=t, heel_strike=hs, **values))
    return frames


def test_every_output_of_every_named_estimator_is_a_column(
    tmp_path: Path, model: TrainedModel, trial: tuple[pd.DataFrame, PipelineConfig]
) -> None:
    sensors, config = trial
    out = tmp_path / "out.csv"
    summary = replay_input_estimators(_input(sensors), out, model, config, ["fp_gf", "tbe", "phase_ekf", "fp_avg"])
    got = pd.read_csv(out)
    # stack (registry) order whatever the order named, each output as <name>.<output>
    expected = ["time_s", "torque_Nm", *(f"{n}.{o}" for n in STACK for o, _ in DECLARED[n].outputs)]
    assert list(got.columns) == expected == list(summary.columns)
    assert "fp_gf.g3" in got.columns and "phase_ekf.stride_length_m" in got.columns
    assert len(got) == len(sensors) == summary.samples
    np.testing.assert_array_equal(got["time_s"].to_numpy(), sensors["time_s"].to_numpy())
    assert [e.name for e in summary.estimators] == STACK and summary.primary == "phase_ekf"
    assert all(e.samples == len(sensors) and e.failed is None for e in summary.estimators)
    assert summary.events == ()


def test_the_columns_are_what_a_live_frame_estimator_makes_of_the_same_frames(
    tmp_path: Path, model: TrainedModel, trial: tuple[pd.DataFrame, PipelineConfig]
) -> None:
    """One sensor-to-estimate path: the frames through a live session's FrameEstimator (without the soft start)
    give every number of the replay's phase_ekf columns and torque, bit for bit."""
    sensors, config = trial
    data = _input(sensors)
    out = tmp_path / "out.csv"
    replay_input_estimators(data, out, model, config, STACK)
    got = _exact(out)

    settings = schema.SessionSettings(primary="phase_ekf")
    channels = {*data.signals, schema.REPLAY_HEEL_STRIKE}
    period = float(np.median(np.diff(data.time_s)))  # the file's sample period, as the replay takes it
    live = FrameEstimator(
        model, config.leg_length, config.body_mass_kg, settings, period, 0.0, soft_start=False,
        estimators=STACK, channels=channels,
    )  # fmt: skip
    ekf = live.stack.names.index("phase_ekf")
    torque, rows = [], []
    for frame in _frames(data):
        torque.append(live.step(frame, 0).torque_Nm)
        assert live.last is not None and live.last.outputs[ekf] is not None
        rows.append(live.last.outputs[ekf])
    expected = np.array(rows)
    for j, name in enumerate(live.stack.outputs[ekf]):
        np.testing.assert_array_equal(got[f"phase_ekf.{name}"], expected[:, j], err_msg=name)
    np.testing.assert_array_equal(got["torque_Nm"], np.array(torque))
    assert got["torque_Nm"].max() > 10.0 and got["phase_ekf.heel_strike"].sum() >= 15


def test_the_fingerprint_filters_track_the_phase_from_the_thigh(
    tmp_path: Path, model: TrainedModel, trial: tuple[pd.DataFrame, PipelineConfig]
) -> None:
    sensors, config = trial
    out = tmp_path / "out.csv"
    summary = replay_input_estimators(_input(sensors), out, model, config, ["fp_avg", "fp_gf"])
    got = pd.read_csv(out)
    assert summary.primary == "fp_avg"  # the first with a phase: no phase_ekf named
    true_rate = float(sensors["gt_phase_rate"].mean())
    late = got["time_s"] > 5.0  # after the filters have locked on
    for name in ("fp_avg", "fp_gf"):
        phase = got[f"{name}.phase"].to_numpy()
        assert np.isfinite(phase).all() and ((phase >= 0.0) & (phase < 1.0)).all(), name
        err = np.angle(np.exp(2j * np.pi * (phase - sensors["gt_phase"].to_numpy()))) / (2 * np.pi)
        assert np.sqrt(np.mean(err[late.to_numpy()] ** 2)) < 0.05, name  # within 5 % of a stride, RMS
        assert abs(float(got[f"{name}.phase_rate"][late].mean()) - true_rate) < 0.05, name
    assert [e.mean_phase_rate is not None and abs(e.mean_phase_rate - true_rate) < 0.1 for e in summary.estimators] == [
        True,
        True,
    ]


def test_an_estimator_the_file_cannot_feed_is_refused_before_anything_is_written(
    tmp_path: Path, model: TrainedModel, trial: tuple[pd.DataFrame, PipelineConfig]
) -> None:
    sensors, config = trial
    seed000 = _input(sensors, [*schema.REPLAY_SIGNALS])  # no thigh angles
    out = tmp_path / "out.csv"
    with pytest.raises(MissingChannels, match=r"fp_avg needs thigh_angle_deg, thigh_vel_dps"):
        replay_input_estimators(seed000, out, model, config, ["phase_ekf", "fp_avg"])
    assert list(tmp_path.iterdir()) == []  # no output, no temporary file
    # an older output is left as it was
    out.write_text("an older output\n")
    with pytest.raises(MissingChannels, match="com_kin needs"):
        replay_input_estimators(seed000, out, model, config, ["com_kin"])
    assert out.read_text() == "an older output\n" and list(tmp_path.iterdir()) == [out]


def test_a_channel_another_estimator_would_derive_is_named_with_it(
    tmp_path: Path, model: TrainedModel, trial: tuple[pd.DataFrame, PipelineConfig]
) -> None:
    sensors, config = trial
    data = _input(sensors, ["foot_angle_deg"])
    data = ReplayInput(data.time_s, data.signals, None)  # no heel strikes: tbe needs them derived
    with pytest.raises(MissingChannels, match=r"tbe needs heel_strike.*name hs_detector or phase_ekf with it"):
        replay_input_estimators(data, tmp_path / "out.csv", model, config, ["tbe"])
    summary = replay_input_estimators(data, tmp_path / "out.csv", model, config, ["hs_detector", "tbe"])
    assert summary.estimators[1].mean_phase_rate is not None and summary.estimators[1].mean_phase_rate > 0.8


def test_unknown_names_are_listed_with_the_known_ones(
    tmp_path: Path, model: TrainedModel, trial: tuple[pd.DataFrame, PipelineConfig]
) -> None:
    sensors, config = trial
    with pytest.raises(ValueError, match=r"unknown estimator phase_kf; gaitscope has .*phase_ekf, tbe") as err:
        replay_input_estimators(_input(sensors), tmp_path / "out.csv", model, config, ["phase_kf", "tbe"])
    assert all(name in str(err.value) for name in ESTIMATORS)
    with pytest.raises(ValueError, match=r"estimates a phase.*add one"):
        replay_input_estimators(_input(sensors), tmp_path / "out.csv", model, config, ["com_kin"])
    with pytest.raises(ValueError, match="all stands alone"):
        replay_input_estimators(_input(sensors), tmp_path / "out.csv", model, config, ["all", "tbe"])
    assert list(tmp_path.iterdir()) == []


def test_all_is_every_estimator_the_files_channels_feed(
    tmp_path: Path, model: TrainedModel, trial: tuple[pd.DataFrame, PipelineConfig]
) -> None:
    sensors, config = trial
    out = tmp_path / "out.csv"
    seed000 = replay_input_estimators(_input(sensors, [*schema.REPLAY_SIGNALS]), out, model, config, ["all"])
    assert [e.name for e in seed000.estimators] == ["hs_detector", "phase_ekf", "tbe", "hs_backup"]
    every = replay_input_estimators(_input(sensors), out, model, config, ["all"])
    names = [e.name for e in every.estimators]
    # fp_ls needs the subject's own fingerprint, which a file does not give
    assert names == [n for n in ESTIMATORS if n != "fp_ls"]
    assert all(e.failed is None and e.samples == len(sensors) for e in every.estimators)
    got = pd.read_csv(out)
    assert got.shape == (len(sensors), len(every.columns))
    knee = got["sdre_knee.knee_sdre_deg"].to_numpy()
    assert np.isfinite(knee).all() and 40.0 < knee.max() - knee.min() < 90.0  # a walking knee's range


def test_parts_join_seamlessly(
    tmp_path: Path, model: TrainedModel, trial: tuple[pd.DataFrame, PipelineConfig], monkeypatch: pytest.MonkeyPatch
) -> None:
    sensors, config = trial
    whole, parts = tmp_path / "whole.csv", tmp_path / "parts.csv"
    replay_input_estimators(_input(sensors), whole, model, config, STACK)
    monkeypatch.setattr(replay_stack, "PART", 333)
    replay_input_estimators(_input(sensors), parts, model, config, STACK)
    assert parts.read_bytes() == whole.read_bytes()


def test_the_named_default_stack_gives_the_default_replays_numbers(tmp_path: Path, model: TrainedModel) -> None:
    """``--estimators phase_ekf,tbe`` on the golden trial: the default replay's phase, torque and tbe phase."""
    config = PipelineConfig(leg_length=0.8778, body_mass_kg=64.37)
    named, default = tmp_path / "named.csv", tmp_path / "default.csv"
    replay_estimators(GOLDEN, named, model, config, ["phase_ekf", "tbe"])
    replay.replay_file(GOLDEN, default, model, config, supervised=True)
    got, expected = pd.read_csv(named), pd.read_csv(default)
    for column, same in (("phase_ekf.phase", "phase"), ("torque_Nm", "torque_Nm"), ("tbe.phase", "tbe_phase")):
        assert np.abs(got[column].to_numpy() - expected[same].to_numpy()).max() <= 1e-9, column


def test_the_command_line(
    tmp_path: Path,
    model: TrainedModel,
    trial: tuple[pd.DataFrame, PipelineConfig],
    capsys: pytest.CaptureFixture[str],
) -> None:
    sensors, config = trial
    subject = ["--leg-length", f"{config.leg_length}", "--mass", f"{config.body_mass_kg}"]
    file = tmp_path / "trial.csv"
    replay_columns(sensors).to_csv(file, index=False)
    out = tmp_path / "out.csv"
    assert main(["replay", str(file), "--out", str(out), "--estimators", "phase_ekf, hs_detector", *subject]) == 0
    printed = capsys.readouterr().out
    assert "stack            hs_detector, phase_ekf (torque follows phase_ekf)" in printed
    assert f"phase_ekf        {len(sensors)}/{len(sensors)} samples with a value; mean phase rate" in printed
    got = pd.read_csv(out)
    assert list(got.columns[:4]) == ["time_s", "torque_Nm", "hs_detector.heel_strike", "phase_ekf.phase"]
    assert math.isclose(float(got["phase_ekf.phase_rate"].mean()), float(sensors["gt_phase_rate"].mean()), abs_tol=0.05)

    # a thigh-only file (and a column that is no channel): the fingerprint filters
    thigh = tmp_path / "thigh.csv"
    sensors[["time_s", *THIGH, "gt_phase"]].to_csv(thigh, index=False)
    assert main(["replay", str(thigh), "--out", str(out), "--estimators", "fp_avg,fp_gf", *subject]) == 0
    printed = capsys.readouterr().out
    assert "stack            fp_avg, fp_gf (torque follows fp_avg)" in printed
    assert "ignored          gt_phase (not channels)" in printed
    got = pd.read_csv(out)
    assert list(got.columns[:3]) == ["time_s", "torque_Nm", "fp_avg.phase"] and got["fp_gf.phase"].notna().all()
    assert main(["replay", str(thigh), "--out", str(tmp_path / "no.csv"), "--estimators", "phase_ekf"]) == 2
    assert "phase_ekf needs foot_angle_deg or shank_angle_deg" in capsys.readouterr().err
    assert not (tmp_path / "no.csv").exists()

    # refused: the file's channels, unknown names, --as-published; exit status 2, nothing written
    refused = tmp_path / "refused.csv"
    for option, words in (
        (["--estimators", "com_kin"], "com_kin needs thigh_angle_deg, thigh_vel_dps"),
        (["--estimators", "nope"], "file --estimators: unknown estimator nope; gaitscope has"),
        (["--estimators", "tbe", "--as-published"], "--as-published is the default stack's"),
    ):
        assert main(["replay", str(file), "--out", str(refused), *option, *subject]) == 2
        assert words in capsys.readouterr().err
        assert not refused.exists()
