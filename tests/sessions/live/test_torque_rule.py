"""The rule for settings changes that can raise the torque (gaitscope.sessions.live.torque_rule), pure, and as a
running session applies it (SessionRuntime.change_settings, the session's injected clock)."""

from __future__ import annotations

import math

import pytest
from fastapi.testclient import TestClient

from gaitscope.sessions import schema
from gaitscope.sessions.live.runtime import SessionRuntime
from gaitscope.sessions.live.settings_change import TorqueRaiseRejected
from gaitscope.sessions.live.sources import LiveDevice
from gaitscope.sessions.live.torque_rule import GaitState, TorqueRaise, assess, raising_fields, refusal
from gaitscope.sessions.schema import TORQUE_RAISE_INTERVAL_S, SessionSettings
from gaitscope.sessions.store_writer import StoreWriter

NOW = SessionSettings()


@pytest.mark.parametrize(
    ("updates", "fields"),
    [
        ({"torque_gain": 1.3}, ["torque_gain"]),
        ({"torque_gain": 0.7}, []),
        ({"max_torque_Nm": 31.0}, ["max_torque_Nm"]),
        ({"max_torque_Nm": 0.0, "torque_gain": 0.5}, []),
        ({"intent_gain_boost": 0.1}, ["intent_gain_boost"]),
        ({"primary": "tbe"}, ["primary"]),
        ({"measurement_noise_scale": 3.0, "process_noise_scale": 0.2}, []),  # the filters' tuning, not the command
        ({"torque_gain": 1.5, "max_torque_Nm": 10.0}, ["torque_gain"]),  # one raise is enough to ask
    ],
)
def test_which_changes_can_raise_the_torque(updates: dict, fields: list[str]) -> None:
    assert raising_fields(NOW, updates) == fields


def test_too_soon_comes_first_then_the_confirmation_then_yes() -> None:
    r = TorqueRaise(["torque_gain"], 14.0, 25.5)
    soon = refusal(r, True, now=101.5, last_raise=100.0, interval=3.0)
    assert soon is not None and soon.reason == "too_soon" and soon.retry_after_s == 1.5
    assert "try again in 1.50 s" in soon.message and "14.0 -> 25.5 N m" in soon.message
    ask = refusal(r, False, now=103.0, last_raise=100.0, interval=3.0)
    assert ask is not None and ask.reason == "confirm" and ask.retry_after_s == 0.0
    assert (ask.peak_before_Nm, ask.peak_after_Nm, ask.fields) == (14.0, 25.5, ["torque_gain"])
    assert refusal(r, True, now=103.0, last_raise=100.0, interval=3.0) is None
    assert refusal(r, True, now=0.0, last_raise=None, interval=3.0) is None


def test_the_peaks_before_and_after(small_model: object) -> None:
    torque = small_model.torque  # type: ignore[attr-defined]
    level = GaitState(torque, math.nan, math.nan)
    r = assess(NOW, NOW.model_copy(update={"torque_gain": 1.8}), ["torque_gain"], level, level, 70.0)
    assert r.peak_after_Nm == pytest.approx(min(1.8 * r.peak_before_Nm, 30.0), abs=0.02)
    idle = GaitState(None, math.nan, math.nan, commands=False)  # nothing drives the torque now
    own = GaitState(None, math.nan, math.nan)  # the new primary commands its own torque: up to the bound
    r = assess(NOW, NOW.model_copy(update={"primary": "gp_ekf"}), ["primary"], idle, own, 70.0)
    assert (r.peak_before_Nm, r.peak_after_Nm) == (0.0, 30.0)


def _runtime(client: TestClient, writer: StoreWriter, now: list[float]) -> SessionRuntime:
    ctx = client.app.state.ctx  # type: ignore[attr-defined]
    r = client.post("/api/subjects", json={"code": "TR01", "leg_length_m": 0.9, "mass_kg": 70})
    body = {"subject_id": r.json()["id"], "source": {"kind": "device"}, "start": False}
    session = ctx.store.get_session(client.post("/api/sessions", json=body).json()["id"])
    model, _ = ctx.models.get(session.settings.model)
    subject = ctx.store.get_subject(session.subject_id)
    return SessionRuntime(
        session, subject, model, LiveDevice(), ctx.store, ctx.settings.data_dir, writer=writer, clock=lambda: now[0]
    )


def test_a_running_session_asks_holds_back_raises_and_never_lowering(client: TestClient) -> None:
    now = [100.0]
    writer = StoreWriter()
    try:
        rt = _runtime(client, writer, now)
        with pytest.raises(TorqueRaiseRejected) as refused:
            rt.change_settings(schema.SettingsChange(torque_gain=1.3))
        detail = refused.value.detail
        assert detail.reason == "confirm" and detail.fields == ["torque_gain"]
        assert 0 < detail.peak_before_Nm < detail.peak_after_Nm
        assert detail.peak_after_Nm == pytest.approx(min(30.0, 1.3 * detail.peak_before_Nm), abs=0.02)
        assert rt.settings.torque_gain == 1.0  # nothing changed
        rt.change_settings(schema.SettingsChange(torque_gain=1.3, confirm=True))
        now[0] += 1.5  # the gain's own rate allows 0.5 after 1 s; the torque rule waits 3 s
        with pytest.raises(TorqueRaiseRejected, match=r"try again in 1\.50 s") as refused:
            rt.change_settings(schema.SettingsChange(torque_gain=1.8, confirm=True))
        assert refused.value.detail.reason == "too_soon"
        # lowering: at once, by any step, unconfirmed, however soon
        assert rt.change_settings(schema.SettingsChange(max_torque_Nm=0.0, torque_gain=0.0)).settings.torque_gain == 0
        assert rt.change_settings(schema.SettingsChange(intent_gain_boost=0.0)).settings.max_torque_Nm == 0.0
        now[0] += TORQUE_RAISE_INTERVAL_S - 1.5
        with pytest.raises(TorqueRaiseRejected) as refused:  # the primary changes what drives the torque
            rt.change_settings(schema.SettingsChange(primary="tbe"))
        assert refused.value.detail.fields == ["primary"]
        assert rt.change_settings(schema.SettingsChange(primary="tbe", confirm=True)).settings.primary == "tbe"
    finally:
        writer.close()
