"""The streaming estimator stack on simulated walking: tracking, heel-strike backup, torque bounds."""

from dataclasses import fields, replace

import numpy as np
import pytest

from gaitscope.estimators.pipeline import GaitEstimate, GaitStatePipeline, PipelineConfig, TrainedModel
from gaitscope.sessions.offline.crossval import stride_rmse, wrapped
from gaitscope.sessions.offline.replay import measurements
from gaitscope.sessions.synth.trials import replay_input, sensor_trial

SCHEDULE = [(1.2, 0.0, 12), (1.0, 5.0, 12), (0.8, -5.0, 12)]


@pytest.fixture(scope="module")
def trial():
    sensors, leg, mass = sensor_trial(SCHEDULE, subject=0)
    data = replay_input(sensors)
    return sensors, data, leg, mass


def _run(model: TrainedModel, trial, config: PipelineConfig, lose_at: float | None = None):
    _, data, _, _ = trial
    z = measurements(data)
    pipe = GaitStatePipeline(model, config, sample_period=0.01)
    phase = np.empty(len(z))
    torque = np.empty(len(z))
    incline = np.empty(len(z))
    lost = False
    for k, t in enumerate(data.time_s):
        if lose_at is not None and not lost and t >= lose_at:
            # knock the filter half a cycle off with a wrong rate and an over-confident covariance
            pipe.ekf.reset(np.array([pipe.ekf.x[0] + 0.5, 0.5, pipe.ekf.x[2], pipe.ekf.x[3]]), 1e-8 * np.eye(4))
            lost = True
        e = pipe.step(float(t), z[k], bool(data.heel_strike[k]), heel_filtered=True)
        phase[k], torque[k], incline[k] = e.phase, e.torque_Nm, e.incline_deg
    return pipe, phase, torque, incline


def test_tracks_phase_and_incline(small_model: TrainedModel, trial) -> None:
    sensors, data, leg, mass = trial
    _, phase, _, incline = _run(small_model, trial, PipelineConfig(leg_length=leg, body_mass_kg=mass))
    hs = data.heel_strike
    err = stride_rmse(wrapped(phase - sensors["gt_phase"].to_numpy()), hs)
    assert np.mean(err[5:]) < 0.03  # under 3 % once converged
    last = sensors["time_s"].to_numpy() > sensors["time_s"].iloc[-1] - 4  # last strides at -5 deg
    assert abs(np.mean(incline[last]) - (-5.0)) < 2.5


def test_backup_recovers_a_lost_filter_within_a_few_strides(small_model: TrainedModel, trial) -> None:
    sensors, data, leg, mass = trial
    t_lose = 8.0
    pipe, phase, _, _ = _run(small_model, trial, PipelineConfig(leg_length=leg, body_mass_kg=mass), lose_at=t_lose)
    assert pipe.backup is not None and pipe.backup.resets >= 1
    t = data.time_s
    hs_times = t[data.heel_strike]
    after = hs_times[hs_times > t_lose]
    window = (t > after[3]) & (t < after[6])  # from the 4th heel strike after the loss on
    err = wrapped(phase[window] - sensors["gt_phase"].to_numpy()[window])
    assert np.sqrt(np.mean(err**2)) < 0.04
    # without the backup the same knock leaves the filter wrong for longer
    _, phase_nb, _, _ = _run(
        small_model,
        trial,
        PipelineConfig(leg_length=leg, body_mass_kg=mass, use_backup=False),
        lose_at=t_lose,
    )
    early = (t > after[0]) & (t < after[3])
    gt = sensors["gt_phase"].to_numpy()[early]
    assert np.sqrt(np.mean(wrapped(phase_nb[early] - gt) ** 2)) > np.sqrt(np.mean(wrapped(phase[early] - gt) ** 2))


def test_torque_is_bounded_plantarflexion_before_cutoff(small_model: TrainedModel, trial) -> None:
    _, _, leg, mass = trial
    config = PipelineConfig(leg_length=leg, body_mass_kg=mass, torque_gain=3.0, max_torque=15.0)
    _, phase, torque, _ = _run(small_model, trial, config)
    assert torque.min() >= 0.0 and torque.max() <= 15.0
    assert np.any(torque == 15.0)  # the bound is active at this gain
    assert np.all(torque[phase > small_model.torque.cutoff_phase] == 0.0)
    peak = _run(small_model, trial, replace(config, torque_gain=1.0, max_torque=200.0))[2].max()
    assert 8.0 < peak < 40.0  # a fifth of a ~1.2-1.6 N m/kg plantarflexor moment


def test_unsafe_torque_bound_is_refused(small_model: TrainedModel) -> None:
    with pytest.raises(ValueError, match=r"max_torque must be within \[0, 200\]"):
        GaitStatePipeline(small_model, PipelineConfig(max_torque=500.0))


def test_time_must_increase(small_model: TrainedModel) -> None:
    pipe = GaitStatePipeline(small_model)
    pipe.step(1.0, np.zeros(6))
    with pytest.raises(ValueError, match="time must increase"):
        pipe.step(1.0, np.zeros(6))


def test_retune_changes_assistance_and_noise_from_the_next_step(small_model: TrainedModel) -> None:
    pipe = GaitStatePipeline(small_model, PipelineConfig(torque_gain=1.0, max_torque=30.0))
    pipe.retune(torque_gain=2.0, max_torque=12.0, measurement_noise_scale=3.0)
    assert pipe.config.torque_gain == 2.0 and pipe.config.max_torque == 12.0
    assert pipe.ekf.config.measurement_noise_scale == 3.0 and pipe.ekf.config.process_noise_scale == 1.0
    np.testing.assert_allclose(pipe.ekf._bins, small_model.noise.bins * 3.0)
    with pytest.raises(ValueError, match="must be >= 0"):
        pipe.retune(max_torque=300.0)
    assert pipe.config.max_torque == 12.0  # a refused change leaves the settings as they were


def test_a_restart_leaves_the_heel_positions_out_until_their_high_pass_settles(
    small_model: TrainedModel, trial
) -> None:
    _, data, _, _ = trial
    z = measurements(data)
    t = data.time_s
    no_heel = z.copy()
    no_heel[:, 4:] = np.nan
    a, b = GaitStatePipeline(small_model), GaitStatePipeline(small_model)
    for p in (a, b):
        p.restart(np.array([0.3, 1.0, 1.0, 0.0]), heel_settle_s=1.0)
    first = t < t[0] + 1.0
    for k in np.flatnonzero(first):  # the first second: as if the heel positions were missing
        ea, eb = a.step(float(t[k]), z[k]), b.step(float(t[k]), no_heel[k])
        assert ea.phase == eb.phase and ea.phase_rate == eb.phase_rate
    k = int(np.argmin(first)) + 50
    for j in range(int(np.argmin(first)), k):  # then they count again
        ea, eb = a.step(float(t[j]), z[j]), b.step(float(t[j]), no_heel[j])
    assert ea.phase != eb.phase
    assert a.restarts == 1


def test_a_step_returns_a_whole_estimate_and_without_a_command_the_same_state(small_model: TrainedModel, trial) -> None:
    """Every field of the estimate is set (it is made without the dataclass's ``__init__``) and it equals the
    one the dataclass makes; ``command=False`` changes the torque (0) and nothing else."""
    _, data, leg, mass = trial
    z = measurements(data)
    config = PipelineConfig(leg_length=leg, body_mass_kg=mass)
    pipe, bare = GaitStatePipeline(small_model, config), GaitStatePipeline(small_model, config)
    for k, t in enumerate(data.time_s[:600]):
        e = pipe.step(float(t), z[k], bool(data.heel_strike[k]))
        b = bare.step(float(t), z[k], bool(data.heel_strike[k]), command=False)
        assert set(vars(e)) == {f.name for f in fields(GaitEstimate)}
        assert e == GaitEstimate(**vars(e)) and hash(e) == hash(GaitEstimate(**vars(e)))
        assert b == replace(e, torque_Nm=0.0) and b.fault == e.fault != "torque"
    np.testing.assert_array_equal(pipe.ekf.x, bare.ekf.x)
