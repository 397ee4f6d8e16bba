"""A session's estimator stack: which estimators run, the primary switch without a torque step, and
isolation of a broken estimator (the others and the torque go on; a failed primary hands over)."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.sessions import registry, schema
from gaitscope.sessions.estimation import FrameEstimator
from gaitscope.sessions.formats.mcap_io import read_messages
from gaitscope.sessions.live.runtime import SessionRuntime, SettingRejected
from gaitscope.sessions.live.sources import LiveDevice, frames_from_table
from gaitscope.sessions.registry import ESTIMATORS, MissingChannels, StackContext, resolve
from gaitscope.sessions.schema import PRIMARY_BLEND_S, GaitState, SensorFrame, SessionSettings
from gaitscope.sessions.synth.cohort import CohortSpec, make_subjects
from gaitscope.sessions.synth.speed_walks import SpeedProtocol, speed_walk
from gaitscope.sessions.synth.trials import replay_columns, sensor_trial
from tests.estimator_doubles import Scripted, register, scripted
from tests.uploads import upload

PERIOD = 0.01
SETTINGS = SessionSettings(torque_gain=2.0, max_torque_Nm=40.0)
#: Largest torque change per sample a blend adds to the primaries' own (N m): bound x dt / blend time.
BLEND_STEP = SETTINGS.max_torque_Nm * PERIOD / PRIMARY_BLEND_S


@pytest.fixture(scope="module")
def walk() -> tuple[list[SensorFrame], float, float]:
    sensors, leg, mass = sensor_trial([(1.2, 0.0, 14)], subject=0, rate_hz=1 / PERIOD)
    return frames_from_table(sensors), leg, mass


def _run(
    model: TrainedModel,
    walk: tuple[list[SensorFrame], float, float],
    settings: SessionSettings = SETTINGS,
    switch: tuple[int, str] | None = None,
    **kw: Any,
) -> tuple[list[GaitState], FrameEstimator]:
    frames, leg, mass = walk
    est = FrameEstimator(model, leg, mass, settings, PERIOD, soft_start=False, **kw)
    out = []
    for k, frame in enumerate(frames):
        if switch is not None and k == switch[0]:
            est.retune(settings.model_copy(update={"primary": switch[1]}))
        out.append(est.step(frame, 0))
    return out, est


def _torque(states: list[GaitState]) -> np.ndarray:
    return np.array([s.torque_Nm for s in states])


# --- which estimators --------------------------------------------------------------------------------
def test_the_default_stack_is_every_estimator_the_channels_allow(small_model: TrainedModel) -> None:
    ctx = StackContext(small_model, 0.9, 70.0, PERIOD)

    def names(channels: set[str] | None, asked: list[str] | None = None) -> list[str]:
        return [e.name for e in resolve(asked, channels, ctx)]

    imus = ["imu_foot", "imu_shank", "imu_thigh", "imu_foot_contra", "imu_shank_contra", "imu_thigh_contra"]
    assert list(ESTIMATORS) == [
        *imus, "hs_detector", "phase_ekf", "tbe", "hs_backup", "fp_avg", "fp_ls", "fp_gf", "com_kin", "intent",
        "sdre_knee",
        "gp_ekf",
    ]  # fmt: skip
    # hs_backup and sdre_knee are opt-in (OPT_IN); fp_ls needs the subject's calibrated fingerprint
    assert names(None) == [*imus, "hs_detector", "phase_ekf", "tbe", "fp_avg", "fp_gf", "com_kin", "intent"]
    # a source that sends the angles and the centre of mass: the front ends deriving them are left out
    assert names(set(schema.CHANNELS)) == ["hs_detector", "phase_ekf", "tbe", "fp_avg", "fp_gf", "intent"]
    # raw IMUs and no angles: the front ends derive them for the phase EKF
    raw = {c for c in schema.CHANNELS if c.startswith(("imu_foot", "imu_shank"))}
    assert names(raw)[:4] == ["imu_foot", "imu_shank", "imu_foot_contra", "imu_shank_contra"]
    assert "phase_ekf" in names(raw)
    assert names({"foot_angle_deg", "thigh_angle_deg"}) == ["hs_detector", "phase_ekf", "tbe", "fp_avg", "fp_gf"]
    assert names(None, ["phase_ekf", "hs_backup"]) == ["phase_ekf", "hs_backup"]
    # a foot angle alone: its velocity is derived, heel strikes detected (the detector feeds the TBE)
    assert names({"foot_angle_deg"}) == ["hs_detector", "phase_ekf", "tbe"]
    # a shank angle alone feeds the phase EKF (its supervisor finds the heel strikes in it), and the TBE
    assert names({"shank_angle_deg", "heel_strike"}) == ["phase_ekf", "tbe"]
    assert names({"foot_angle_deg"}, ["tbe", "phase_ekf"]) == ["phase_ekf", "tbe"]  # run in registry order
    with pytest.raises(
        MissingChannels, match="phase_ekf needs foot_angle_deg or shank_angle_deg; tbe needs heel_strike"
    ):
        resolve(["phase_ekf", "tbe"], {"thigh_angle_deg"}, ctx)
    assert names({"shank_angle_deg"}, ["phase_ekf", "tbe"]) == ["phase_ekf", "tbe"]  # its heel strikes feed the TBE
    with pytest.raises(MissingChannels, match=r"channels \(belt_speed_m_s\) feed no estimator"):
        resolve(None, {"belt_speed_m_s"}, ctx)
    with pytest.raises(ValueError, match="unknown estimator nope"):
        resolve(["nope"], None, ctx)
    assert registry.choose_primary("fp_avg", resolve(None, {"shank_angle_deg", "heel_strike"}, ctx)) == "phase_ekf"


def test_the_default_stack_keeps_the_gait_state_of_the_phase_ekf(small_model: TrainedModel, walk) -> None:
    """The primary's outputs are the gait state; the other estimators change nothing of it."""
    full, est = _run(small_model, walk)
    alone, _ = _run(small_model, walk, estimators=["phase_ekf", "tbe"])
    imus = ("imu_foot", "imu_shank", "imu_thigh", "imu_foot_contra", "imu_shank_contra", "imu_thigh_contra")
    assert est.stack.names == (*imus, "hs_detector", "phase_ekf", "tbe", "fp_avg", "fp_gf", "com_kin", "intent")
    assert est.primary == "phase_ekf"
    for a, b in zip(full, alone, strict=True):
        assert a.model_dump() == b.model_dump()
    k = est.stack.names.index("tbe")
    tbe = est.stack.outputs[k].index("phase")
    assert est.last is not None and full[-1].tbe_phase == est.last.outputs[k][tbe]  # type: ignore[index]
    assert sum(s.heel_strike for s in full) >= 12 and max(s.torque_Nm for s in full) > 10.0


# --- what is shown is what some estimator estimated -----------------------------------------------------
def test_a_timing_based_primary_shows_the_slope_another_estimator_estimates_or_none(small_model: TrainedModel) -> None:
    """Issue #23: the timing-based estimate estimates no incline or stride length. With the phase EKF beside it,
    those come from the phase EKF (named as their source); alone, they are not estimated (None), never the
    nominal values its torque profile assumes (which are stated apart)."""
    sensors, leg, mass = sensor_trial([(1.2, 10.0, 8), (1.2, -10.0, 8)], subject=0, rate_hz=1 / PERIOD)
    slope = (frames_from_table(sensors), leg, mass)
    tbe = SETTINGS.model_copy(update={"primary": "tbe"})
    both, est = _run(small_model, slope, tbe, estimators=["phase_ekf", "tbe"])
    assert both[0].sources == {
        "phase": "tbe", "phase_rate": "tbe", "stride_length_m": "phase_ekf", "incline_deg": "phase_ekf",
        "foot_pred_deg": "phase_ekf", "shank_pred_deg": "phase_ekf",
    }  # fmt: skip
    assert both[0].torque_assumes == {"stride_length_m": pytest.approx(1.3 * leg), "incline_deg": 0.0}
    assert all(s.sources is None for s in both[1:])  # sent again only when they change
    k = est.stack.names.index("phase_ekf")
    assert est.last is not None and both[-1].incline_deg == est.last.outputs[k][3]  # type: ignore[index]
    uphill = [s.incline_deg for s in both[500:850] if s.incline_deg is not None]
    downhill = [s.incline_deg for s in both[1400:1700] if s.incline_deg is not None]
    assert np.mean(uphill) > 5.0 and np.mean(downhill) < -5.0  # the slope, not a level 0
    alone, _ = _run(small_model, slope, tbe, estimators=["tbe"])
    assert alone[0].sources == {"phase": "tbe", "phase_rate": "tbe"}
    assert all(s.incline_deg is None and s.stride_length_m is None for s in alone)
    assert all(s.foot_pred_deg is None and s.shank_pred_deg is None for s in alone)
    assert all(s.phase is not None for s in alone) and max(s.torque_Nm for s in alone) > 10.0  # assists on
    assert est.stack.outputs[k][3] == "incline_deg"


# --- primary switch ----------------------------------------------------------------------------------
def test_switching_the_primary_while_walking_does_not_step_the_torque(small_model: TrainedModel, walk) -> None:
    def shifted() -> Scripted:
        return Scripted("shifted", shift=0.35)  # a phase a third of a cycle off: a very different torque

    ekf = _torque(_run(small_model, walk, extra=[shifted()])[0])
    other = _torque(_run(small_model, walk, SETTINGS.model_copy(update={"primary": "shifted"}), extra=[shifted()])[0])
    settle = 200
    normal = max(np.abs(np.diff(ekf[settle:])).max(), np.abs(np.diff(other[settle:])).max())
    k = settle + int(np.argmax(np.abs(ekf - other)[settle:-100]))  # switch where they differ most
    assert abs(ekf[k] - other[k]) > 10.0

    states, est = _run(small_model, walk, switch=(k, "shifted"), extra=[shifted()])
    blended = _torque(states)
    steps = np.abs(np.diff(blended))
    assert steps[k - 1 : k + 60].max() <= normal + BLEND_STEP + 1e-9
    np.testing.assert_array_equal(blended[:k], ekf[:k])  # the old primary's up to the switch
    done = k + round(PRIMARY_BLEND_S / PERIOD) + 1
    np.testing.assert_array_equal(blended[done:], other[done:])  # the new one's once blended
    assert est.primary == "shifted" and est.last is not None and est.last.outputs[-1] is not None
    assert states[-1].phase == est.last.outputs[-1][0]

    abrupt = _torque(_run(small_model, walk, switch=(k, "shifted"), extra=[shifted()], blend_s=0.0)[0])
    assert abs(abrupt[k] - abrupt[k - 1]) > normal + BLEND_STEP  # without the blend it would step


def test_a_primary_must_be_in_the_stack_estimate_a_phase_and_be_healthy(small_model: TrainedModel, walk) -> None:
    frames, leg, mass = walk
    est = FrameEstimator(small_model, leg, mass, SETTINGS, PERIOD, extra=[Scripted("broken", raise_after=0)])
    for name, why in (("nope", "not in the session's stack"), ("hs_detector", "estimates no phase")):
        with pytest.raises(ValueError, match=why):
            est.stack.set_primary(name)
    est.step(frames[0], 0)
    with pytest.raises(ValueError, match=r"broken has failed \(raised RuntimeError: boom\)"):
        est.stack.set_primary("broken")
    assert est.primary == "phase_ekf"


# --- isolation -----------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("broken", "reason"),
    [
        (Scripted("broken", raise_after=300), "raised RuntimeError: boom"),
        (Scripted("broken", nan_after=300), "returned a non-finite phase"),
        (Scripted("broken", diverge_after=300), "its covariance diverged"),
    ],
    ids=["raises", "nan", "diverges"],
)
def test_a_broken_estimator_is_isolated(small_model: TrainedModel, walk, broken: Scripted, reason: str) -> None:
    reference, _ = _run(small_model, walk)
    states, est = _run(small_model, walk, extra=[broken])
    assert list(est.stack.failed) == ["broken"] and reason in est.stack.failed["broken"]
    [event] = est.events
    assert event.startswith("estimator broken failed at ") and reason in event
    for a, b in zip(states, reference, strict=True):  # the others and the torque went on, untouched
        assert a.model_dump() == b.model_dump()
    assert est.last is not None and est.last.outputs[-1] is None
    assert all(y is not None for y in est.last.outputs[:-1])
    assert broken.samples < 310 < len(states)  # not stepped again once failed


def test_a_failed_primary_hands_the_torque_to_the_tbe(small_model: TrainedModel, walk) -> None:
    k = 500
    settings = SETTINGS.model_copy(update={"primary": "broken"})
    states, est = _run(small_model, walk, settings, extra=[Scripted("broken", shift=0.3, raise_after=k)])
    tbe, _ = _run(small_model, walk, SETTINGS.model_copy(update={"primary": "tbe"}))
    torque, tbe_torque = _torque(states), _torque(tbe)
    assert est.primary == "tbe" and est.stack.requested == "broken"
    assert (
        est.events[-1].startswith("primary estimator broken failed at")
        and "now follows Timing-based estimate" in est.events[-1]
    )
    assert states[k].fault and not states[k + 1].fault
    assert np.all(np.isfinite(torque)) and torque.min() >= 0.0 and torque.max() <= SETTINGS.max_torque_Nm
    normal = max(np.abs(np.diff(torque[200:k])).max(), np.abs(np.diff(tbe_torque[200:])).max())
    assert np.abs(np.diff(torque[k - 1 : k + 60])).max() <= normal + BLEND_STEP + 1e-9
    done = k + round(PRIMARY_BLEND_S / PERIOD) + 1
    np.testing.assert_array_equal(torque[done:], tbe_torque[done:])
    assert [s.phase for s in states[done:]] == [s.phase for s in tbe[done:]]


def test_the_phase_ekf_failing_as_primary_hands_over_too(small_model: TrainedModel, walk) -> None:
    frames, leg, mass = walk
    est = FrameEstimator(small_model, leg, mass, SETTINGS, PERIOD, soft_start=False)
    ekf = est.stack.estimators[est.stack.names.index("phase_ekf")]
    for frame in frames[:400]:
        est.step(frame, 0)

    def broken(t: float, z: np.ndarray) -> np.ndarray:
        raise FloatingPointError("overflow in the update")

    ekf.step = broken  # type: ignore[method-assign]
    torques = [est.step(frame, 0).torque_Nm for frame in frames[400:]]
    assert est.stack.failed == {"phase_ekf": "raised FloatingPointError: overflow in the update"}
    assert est.primary == "tbe" and all(0.0 <= q <= SETTINGS.max_torque_Nm for q in torques)
    assert max(torques[60:]) > 10.0  # assistance goes on, on the timing-based phase


def test_without_a_fallback_the_torque_ramps_down_to_zero(small_model: TrainedModel, walk) -> None:
    k = 500
    settings = SETTINGS.model_copy(update={"primary": "broken"})
    broken = Scripted("broken", raise_after=k)
    states, est = _run(small_model, walk, settings, estimators=["phase_ekf"], extra=[broken])
    torque = _torque(states)
    assert est.primary is None and "no fallback" in est.events[-1]
    ramp = round(PRIMARY_BLEND_S / PERIOD)
    assert np.abs(np.diff(torque[k - 1 : k + ramp + 1])).max() <= torque[k - 1] * PERIOD / PRIMARY_BLEND_S + 1e-9
    assert np.all(torque[k + ramp :] == 0.0)
    # no estimator drives the torque: no phase is shown; what phase_ekf still estimates is, named as its
    assert states[-1].phase is None and est.stack.sources == {
        q: "phase_ekf" for q in ("phase_rate", "stride_length_m", "incline_deg", "foot_pred_deg", "shank_pred_deg")
    }
    [announced] = [s.sources for s in states[k:] if s.sources is not None]
    assert announced == est.stack.sources and "phase" not in announced


def test_an_estimator_whose_retune_raises_fails_alone(small_model: TrainedModel, walk) -> None:
    frames, leg, mass = walk

    class Untunable(Scripted):
        tunables = ("measurement_noise_scale",)

        def retune(self, **params: float) -> None:
            raise ValueError("cannot")

    est = FrameEstimator(small_model, leg, mass, SETTINGS, PERIOD, extra=[Untunable("picky")])
    est.retune(SETTINGS.model_copy(update={"measurement_noise_scale": 2.0}))
    assert est.stack.failed == {"picky": "retune raised ValueError: cannot"}
    assert est.events == ["estimator picky failed: retune raised ValueError: cannot"]
    assert est.step(frames[0], 0).t == 0.0


# --- a primary with its own torque: the GP-EKF's control surface (seed 003) --------------------------
#: Seed 003's walk of VC01 at 100 Hz: speed 0.4-1.2 m/s, then a sudden stop in mid-stance (20.7 s, as in
#: tests/estimators/test_gp_ekf.py) and standing
SPEED_WALK = SpeedProtocol(walk_s=20.7, standing_s=6.0, rate_hz=1 / PERIOD)
GP_SETTINGS = SETTINGS.model_copy(update={"primary": "gp_ekf", "estimators": ["phase_ekf", "tbe", "gp_ekf"]})


@pytest.fixture(scope="module")
def speed_walk_frames() -> tuple[list[SensorFrame], float, float]:
    subject = make_subjects(CohortSpec())[0]
    table = speed_walk(subject, SPEED_WALK)
    channels = [c for c in table.columns if c in schema.CHANNELS]
    return frames_from_table(table[["time_s", *channels]]), subject.leg_length_m, subject.mass_kg


def _gp_outputs(est: FrameEstimator) -> dict[str, float]:
    assert est.last is not None
    k = est.stack.names.index("gp_ekf")
    y = est.last.outputs[k]
    assert y is not None
    return dict(zip(est.stack.outputs[k], y.tolist(), strict=True))


def test_the_gp_ekf_as_primary_drives_the_torque_with_its_own_control_surface(
    small_model: TrainedModel, speed_walk_frames: tuple[list[SensorFrame], float, float]
) -> None:
    """Its ``torque_Nm`` (the surface over stance phase and phase rate), times the gain, within the bound,
    to 0 standing: not the torque profile at its (stance) phase."""
    frames, leg, mass = speed_walk_frames
    commands = []
    for gain, bound in ((2.0, 40.0), (3.0, 5.0)):
        settings = GP_SETTINGS.model_copy(update={"torque_gain": gain, "max_torque_Nm": bound})
        est = FrameEstimator(small_model, leg, mass, settings, PERIOD, soft_start=False)
        torque, own, stance, still = [], [], [], []
        for frame in frames:
            torque.append(est.step(frame, 0).torque_Nm)
            y = _gp_outputs(est)
            own.append(y["torque_Nm"])
            stance.append(y["in_stance"] == 1.0)
            still.append(y["standing"])
            assert torque[-1] == min(max(y["torque_Nm"] * gain, 0.0), bound) * (1.0 - y["standing"])
        tau, surface, in_stance = np.array(torque), np.array(own), np.array(stance)
        assert np.all(tau[~in_stance] == 0.0) and tau[in_stance].max() == min(surface.max() * gain, bound)
        assert 0.5 * bound < tau.max() <= bound  # push-off: 0.2 x the biological moment, x the gain
        standing = np.array(still) == 1.0  # the phase rate fell to 0 after the sudden stop
        assert standing[-100:].all() and np.all(tau[standing] == 0.0) and tau[-1] == 0.0
        commands.append(tau)
    profile, _ = _run(small_model, speed_walk_frames, GP_SETTINGS.model_copy(update={"primary": "phase_ekf"}))
    assert np.abs(_torque(profile) - commands[0]).max() > 10.0  # the profile at its phase: another torque


def test_switching_to_the_gp_ekf_blends_from_the_profile_to_its_surface(
    small_model: TrainedModel, speed_walk_frames: tuple[list[SensorFrame], float, float]
) -> None:
    ekf = _torque(_run(small_model, speed_walk_frames, GP_SETTINGS.model_copy(update={"primary": "phase_ekf"}))[0])
    gp = _torque(_run(small_model, speed_walk_frames, GP_SETTINGS)[0])
    settle = 300
    normal = max(np.abs(np.diff(ekf[settle:])).max(), np.abs(np.diff(gp[settle:])).max())
    k = settle + int(np.argmax(np.abs(ekf - gp)[settle:-100]))  # switch where they differ most
    assert abs(ekf[k] - gp[k]) > 5.0
    states, est = _run(
        small_model, speed_walk_frames, GP_SETTINGS.model_copy(update={"primary": "phase_ekf"}), switch=(k, "gp_ekf")
    )
    blended = _torque(states)
    assert np.abs(np.diff(blended))[k - 1 : k + 60].max() <= normal + BLEND_STEP + 1e-9
    np.testing.assert_array_equal(blended[:k], ekf[:k])
    done = k + round(PRIMARY_BLEND_S / PERIOD) + 1
    np.testing.assert_array_equal(blended[done:], gp[done:])
    assert est.primary == "gp_ekf"


# --- sessions ------------------------------------------------------------------------------------------
def _subject(client: TestClient) -> int:
    r = client.post(
        "/api/subjects", json={"code": f"S{time.monotonic_ns() % 10**8}", "leg_length_m": 0.9, "mass_kg": 70}
    )
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def test_a_session_refuses_an_estimator_its_source_cannot_feed(client: TestClient, tmp_path: Path) -> None:
    sensors, _, _ = sensor_trial([(1.0, 0.0, 4)], rate_hz=100.0)
    table = replay_columns(sensors)[["time_s", "shank_angle_deg", "heel_strike"]]  # no foot sensor
    path = tmp_path / "shank_only.csv"
    table.to_csv(path, index=False, float_format="%.6f")
    subject = _subject(client)
    trial = upload(client, path, subject)
    source = {"kind": "replay", "trial_id": trial["id"], "speed": 50.0}
    asked = {"subject_id": subject, "source": source, "settings": {"estimators": ["phase_ekf", "fp_avg"]}}
    r = client.post("/api/sessions", json=asked)
    assert r.status_code == 409, r.text
    assert "fp_avg needs thigh_angle_deg" in r.json()["detail"] and "phase_ekf" not in r.json()["detail"]
    [refused] = [s for s in client.get("/api/sessions").json() if s["settings"]["estimators"]]
    assert refused["state"] == "failed"
    events = client.get(f"/api/sessions/{refused['id']}/events").json()
    assert any("refused to start" in e["text"] and "thigh_angle_deg" in e["text"] for e in events)
    # By default the session runs what the channels allow: the phase EKF on the shank angle drives the torque.
    r = client.post("/api/sessions", json={"subject_id": subject, "source": source})
    assert r.status_code == 201, r.text
    runtime = client.app.state.ctx.manager.get(r.json()["id"])  # type: ignore[attr-defined]
    assert runtime.estimator.stack.names == ("phase_ekf", "tbe") and runtime.estimator.primary == "phase_ekf"
    client.post(f"/api/sessions/{r.json()['id']}/stop")


def test_a_running_session_records_streams_and_reports_every_estimator(
    client: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Through the real runtime: a broken estimator of the stack fails alone (event, data health, its
    recorded channel), the primary switches through the settings path (logged, rate-limited)."""
    register(monkeypatch, scripted("broken", nan_after=150))
    ctx = client.app.state.ctx  # type: ignore[attr-defined]
    settings = {"estimators": ["phase_ekf", "tbe", "broken"]}
    r = client.post(
        "/api/sessions",
        json={"subject_id": _subject(client), "source": {"kind": "device"}, "settings": settings, "start": False},
    )
    assert r.status_code == 201, r.text
    session = ctx.store.get_session(r.json()["id"])
    model, _ = ctx.models.get("default")
    runtime = SessionRuntime(
        session, ctx.store.get_subject(session.subject_id), model, LiveDevice(), ctx.store, ctx.settings.data_dir
    )
    trial = runtime.start_recording("stack")
    sub = runtime.subscribe(0.0)
    sensors, _, _ = sensor_trial([(1.2, 0.0, 8)], rate_hz=100.0)
    frames = frames_from_table(sensors)
    for i, frame in enumerate(frames):
        if i == 300:
            runtime.change_settings(schema.SettingsChange(primary="tbe", reason="compare", confirm=True))
            with pytest.raises(SettingRejected, match="switches are at least 2 s apart"):
                runtime.change_settings(schema.SettingsChange(primary="phase_ekf"))
            for name, why in (("broken", "has failed"), ("nope", "not in the session's stack")):
                with pytest.raises(SettingRejected, match=why):
                    runtime.change_settings(schema.SettingsChange(primary=name))
        runtime.process(frame, time.time_ns())
    health = runtime.health(sub)
    assert health.estimators == ["phase_ekf", "tbe", "broken"] and health.primary == "tbe"
    assert list(health.failed_estimators) == ["broken"] and "non-finite phase" in health.failed_estimators["broken"]
    batch = sub.batch(session.id)
    assert set(batch.estimators) == {"phase_ekf", "tbe", "broken"} and batch.estimators["broken"].failed
    assert len(batch.estimators["tbe"].columns["phase"]) == len(batch.states) == len(frames)
    streamed = batch.estimators["tbe"].columns["phase"][-5:]
    assert streamed == pytest.approx([s.phase for s in batch.states[-5:]], abs=1e-5)
    assert set(batch.estimators["phase_ekf"].columns) == {"phase", "phase_rate", "stride_length_m", "incline_deg"}
    runtime.stop_recording()

    events = ctx.store.list_events(session.id)
    texts = [e.text for e in events]
    assert any(
        t.startswith("estimator Scripted double broken failed at 1.500 s: returned a non-finite phase") for t in texts
    )
    [change] = [e for e in events if e.kind == "setting"]
    assert (change.field, change.before, change.after) == ("primary", "phase_ekf", "tbe")
    # in the screen's words (issue #23), the machine names in field, before and after
    follows = "Torque follows Phase EKF (seed 000) → Timing-based estimate"
    assert change.text == f"{follows}, the torque blends over 0.5 s (compare)"
    path = ctx.settings.data_dir / trial.path
    recorded = {name: [m for _, _, m in read_messages(path, [f"/estimators/{name}"])] for name in ("tbe", "broken")}
    assert len(recorded["tbe"]) == len(frames) and recorded["tbe"][0]["values"].keys() == {"phase", "phase_rate"}
    assert [m["failed"] for m in recorded["broken"]].index(True) == 150
    assert recorded["broken"][-1]["values"] == {"phase": None, "phase_rate": None}
    # written as prepared JSON on the hot path: it reads back as the class, field for field
    last = schema.EstimatorOutputs.model_validate(recorded["tbe"][-1])
    assert (last.name, last.seq, last.failed) == ("tbe", frames[-1].seq, False)
    assert recorded["tbe"][-1] == last.model_dump()
    settings_msgs = [m for _, _, m in read_messages(path, ["/settings"])]
    assert [m["primary"] for m in settings_msgs] == ["phase_ekf", "tbe"]
    assert all(math.isfinite(m["torque_Nm"]) for _, _, m in read_messages(path, ["/torque"]))


def test_a_session_streams_the_speed_change_intent_the_live_view_reads(client: TestClient) -> None:
    ctx = client.app.state.ctx  # type: ignore[attr-defined]
    settings = {"estimators": ["phase_ekf", "intent"]}
    r = client.post(
        "/api/sessions",
        json={"subject_id": _subject(client), "source": {"kind": "device"}, "settings": settings, "start": False},
    )
    session = ctx.store.get_session(r.json()["id"])
    model, _ = ctx.models.get("default")
    runtime = SessionRuntime(
        session, ctx.store.get_subject(session.subject_id), model, LiveDevice(), ctx.store, ctx.settings.data_dir
    )
    sub = runtime.subscribe(0.0)
    sensors, _, _ = sensor_trial([(1.0, 0.0, 6), (1.3, 0.0, 6)], rate_hz=100.0)
    for frame in frames_from_table(sensors):
        runtime.process(frame, time.time_ns())
    columns = sub.batch(session.id).estimators["intent"].columns
    assert set(columns) == {"desired_speed_m_s", "intent_code", "intent_confidence", "speed_m_s"}
    codes = [c for c in columns["intent_code"] if c is not None]
    assert set(codes) <= {-1.0, 0.0, 1.0} and 1.0 in codes  # the walker sped up
    assert all(v is not None and 0.2 < v < 2.5 for v in columns["desired_speed_m_s"][-100:])


def test_standing_still_takes_the_torque_to_zero_and_walking_again_restarts_with_events(
    small_model: TrainedModel,
) -> None:
    """A walk with bouts between standing (issue #10): the session's torque is 0 while the walker stands
    (after the ramp), each standing and each resumption is a note for the event log, and the torque is
    finite and within the bound throughout."""
    from gaitscope.sessions.synth.real_walks import RealWalkSpec, real_walk

    subject = make_subjects(CohortSpec())[0]
    walk = real_walk(subject, RealWalkSpec(bouts=2, dropouts_per_min=0.0))
    frames = list(frames_from_table(walk[["time_s", *schema.REPLAY_SIGNALS]]))
    est = FrameEstimator(small_model, subject.leg_length_m, subject.mass_kg, SETTINGS, PERIOD, soft_start=False)
    est.retune(SETTINGS.model_copy(update={"estimators": None}))
    states, notes = [], []
    for frame in frames:
        states.append(est.step(frame, 0))
        notes += est.notes
        est.notes.clear()
    torque = _torque(states)
    assert np.isfinite(torque).all() and (torque >= 0).all() and (torque <= SETTINGS.max_torque_Nm).all()
    still = walk["condition"].to_numpy() == "standing"
    t = walk["time_s"].to_numpy()
    settled = still & (t - np.maximum.accumulate(np.where(~still, t, t[0])) > 1.5)  # standing for 1.5 s
    assert settled.any() and (torque[settled] == 0.0).all()
    assert torque[~still].max() > 1.0  # walking is assisted
    assert sum("standing still" in n for n in notes) >= 2
    assert sum("walking resumed after standing still" in n for n in notes) == 2


def test_an_imu_front_end_whose_sensor_sends_nothing_derives_no_channel(small_model: TrainedModel) -> None:
    from gaitscope.estimators.imu_frontend import G0, ImuFrontEnd, imu_inputs
    from gaitscope.sessions.stack import EstimatorStack

    front = [ImuFrontEnd("foot"), Scripted("timing")]
    stack = EstimatorStack(front, small_model.torque, 0.9, 70.0, primary="timing")
    raw = dict(zip(imu_inputs("foot"), (0.0, 0.0, 5.0, 0.0, G0, 0.0), strict=True))
    for k in range(50):
        channels = dict(raw) | {"heel_strike": 0.0}
        stack.step(k * 0.01, channels)
        assert math.isfinite(channels["foot_angle_deg"]) and channels["foot_vel_dps"] == pytest.approx(5.0, abs=1.0)
    gone = {c: math.nan for c in raw}
    channels = dict(gone)
    sample = stack.step(0.5, channels)
    held = sample.outputs[0]
    assert held is not None and math.isfinite(held[0])  # the front end holds its angle for itself
    assert math.isnan(channels.get("foot_angle_deg", math.nan)) and math.isnan(channels.get("foot_vel_dps", math.nan))
