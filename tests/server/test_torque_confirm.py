"""The torque rule over the API (issue #23, 4): through the real app, a settings change or an undo that can raise
the torque is refused without ``confirm`` (409 naming the peaks before and after), made with it, held back when
too soon after the last; lowering is always accepted; ``/settings/check`` says the same, changing nothing. And no
sequence of unconfirmed changes raises the peak torque (hypothesis)."""

from __future__ import annotations

import json
from typing import Any

import pytest
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gaitscope.sessions.schema import SETTING_LIMITS, TORQUE_RAISE_INTERVAL_S, AuditQuery
from tests.waiting import ShiftedClock


def _device_session(client: TestClient, code: str = "TQ01", **settings: Any) -> int:
    """A running device session that no frame has reached: its gait state is the nominal one, fixed."""
    subject = client.post("/api/subjects", json={"code": code, "leg_length_m": 0.9, "mass_kg": 70.0}).json()["id"]
    body = {"subject_id": subject, "source": {"kind": "device"}, "settings": settings}
    r = client.post("/api/sessions", json=body)
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def _peak_now(client: TestClient, sid: int) -> float:
    r = client.post(f"/api/sessions/{sid}/settings/check", json={})
    assert r.status_code == 200, r.text
    return float(r.json()["peak_before_Nm"])


@pytest.fixture
def clock(client: TestClient) -> ShiftedClock:
    clock = ShiftedClock()
    client.app.state.ctx.manager.clock = clock  # type: ignore[attr-defined]  # the rate limits read it
    return clock


def test_a_raise_asks_with_the_peaks_is_made_confirmed_and_held_back_when_too_soon(
    client: TestClient, clock: ShiftedClock
) -> None:
    sid = _device_session(client)
    url = f"/api/sessions/{sid}/settings"
    check = client.post(f"{url}/check", json={"torque_gain": 1.3}).json()
    assert check["fields"] == ["torque_gain"] and check["retry_after_s"] == 0.0
    r = client.patch(url, json={"torque_gain": 1.3})
    assert r.status_code == 409, r.text
    detail = r.json()["detail"]
    assert detail["reason"] == "confirm" and detail["fields"] == ["torque_gain"]
    before, after = detail["peak_before_Nm"], detail["peak_after_Nm"]
    assert (before, after) == (check["peak_before_Nm"], check["peak_after_Nm"])
    assert 5.0 < before < after == pytest.approx(min(30.0, 1.3 * before), abs=0.02)
    assert f"{before:.1f} -> {after:.1f} N m" in detail["message"]
    assert client.get(f"/api/sessions/{sid}").json()["settings"]["torque_gain"] == 1.0  # nothing changed
    r = client.patch(url, json={"torque_gain": 1.3, "confirm": True})
    assert r.status_code == 200 and r.json()["settings"]["torque_gain"] == 1.3
    audit = client.app.state.ctx.audit  # type: ignore[attr-defined]
    entries = [json.loads(e.after) for e in audit.list(AuditQuery(action="settings.change"))]
    assert {"torque_gain": 1.3, "confirm": True} in entries and {"torque_gain": 1.3} in entries  # confirmed, said so
    clock.advance(1.5)  # the 1.0 -> 1.3 -> 1.8, 1.5 s apart: the gain's own rate allows it, the rule not
    r = client.patch(url, json={"torque_gain": 1.8, "confirm": True})
    assert r.status_code == 409 and r.json()["detail"]["reason"] == "too_soon"
    assert 1.0 < r.json()["detail"]["retry_after_s"] <= TORQUE_RAISE_INTERVAL_S - 1.5  # (real time runs on too)
    assert "try again in" in r.json()["detail"]["message"]
    assert client.post(f"{url}/check", json={"torque_gain": 1.8}).json()["retry_after_s"] > 1.0
    clock.advance(TORQUE_RAISE_INTERVAL_S - 1.5)
    r = client.patch(url, json={"torque_gain": 1.8, "confirm": True})
    assert r.status_code == 200 and r.json()["settings"]["torque_gain"] == 1.8


def test_lowering_is_always_accepted_at_once_by_any_step(client: TestClient, clock: ShiftedClock) -> None:
    sid = _device_session(client, torque_gain=3.0, max_torque_Nm=80.0, intent_gain_boost=0.3)
    url = f"/api/sessions/{sid}/settings"
    assert client.post(f"{url}/check", json={"torque_gain": 0.0}).json()["fields"] == []
    for change in ({"torque_gain": 0.5}, {"max_torque_Nm": 0.0}, {"intent_gain_boost": 0.0}, {"torque_gain": 0.0}):
        r = client.patch(url, json=change)  # no confirm, no wait, steps far over the rates of a raise
        assert r.status_code == 200, r.text
    assert _peak_now(client, sid) == 0.0


def test_an_undo_that_raises_asks_and_a_primary_switch_asks(client: TestClient, clock: ShiftedClock) -> None:
    sid = _device_session(client, estimators=["phase_ekf", "tbe"])
    url = f"/api/sessions/{sid}/settings"
    assert client.patch(url, json={"max_torque_Nm": 5.0}).status_code == 200  # lowering: at once
    assert client.patch(url, json={"max_torque_Nm": 25.0}).status_code == 409  # raising: asks
    clock.advance(1.0)  # the maximum torque's own rate: a step of 25 N m back is more than 10 a step
    r = client.post(f"{url}/undo", json={})
    assert r.status_code == 409 and "at most 10 per step" in r.text, r.text
    assert client.patch(url, json={"max_torque_Nm": 10.0}).status_code == 409  # it asks
    r = client.patch(url, json={"max_torque_Nm": 15.0})
    assert r.status_code == 409, r.text
    r = r.json()["detail"]
    assert r["peak_before_Nm"] == 5.0 and r["peak_after_Nm"] > 10.0 and r["fields"] == ["max_torque_Nm"]
    assert client.patch(url, json={"max_torque_Nm": 15.0, "confirm": True}).status_code == 200
    clock.advance(TORQUE_RAISE_INTERVAL_S)
    # (an event between: no frame has reached the session, so both changes are at session time 0 and would
    # otherwise count as one change to undo, gaitscope.sessions.live.undo.last_change)
    assert client.post(f"/api/sessions/{sid}/annotations", json={"text": "lower"}).status_code == 201
    assert client.patch(url, json={"max_torque_Nm": 10.0}).status_code == 200  # lowering: at once, unasked
    clock.advance(1.0)
    r = client.post(f"{url}/undo", json={})  # back to 15 N m raises the torque: it asks
    assert r.status_code == 409 and isinstance(r.json()["detail"], dict), r.text
    assert r.json()["detail"]["reason"] == "confirm" and r.json()["detail"]["fields"] == ["max_torque_Nm"]
    assert r.json()["detail"]["peak_before_Nm"] == 10.0 < r.json()["detail"]["peak_after_Nm"]
    r = client.post(f"{url}/undo", json={"confirm": True})
    assert r.status_code == 200 and r.json()["settings"]["max_torque_Nm"] == 15.0
    clock.advance(TORQUE_RAISE_INTERVAL_S)
    r = client.patch(url, json={"primary": "tbe"})
    assert r.status_code == 409 and r.json()["detail"]["fields"] == ["primary"]
    r = client.patch(url, json={"primary": "tbe", "confirm": True})
    assert r.status_code == 200 and r.json()["settings"]["primary"] == "tbe"


def test_check_needs_a_running_session(client: TestClient) -> None:
    assert client.post("/api/sessions/999/settings/check", json={}).status_code == 404


_change = st.fixed_dictionaries(
    {},
    optional={
        name: st.floats(lo, hi, allow_nan=False).map(lambda x: round(x, 2))
        for name, (lo, hi, _) in SETTING_LIMITS.items()
    }
    | {"primary": st.sampled_from(["phase_ekf", "tbe"])},
)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(changes=st.lists(_change, min_size=1, max_size=6))
def test_no_sequence_of_unconfirmed_changes_raises_the_peak_torque(
    client: TestClient, clock: ShiftedClock, changes: list[dict[str, Any]]
) -> None:
    ctx = client.app.state.ctx  # type: ignore[attr-defined]
    sid = next((s.id for s in ctx.store.list_sessions(None) if s.state == "running"), None)
    if sid is None:  # one session for every example: the state one example leaves is the next one's start
        sid = _device_session(client, "TQP1", estimators=["phase_ekf", "tbe"])
    url = f"/api/sessions/{sid}/settings"
    for change in changes:
        before = client.get(f"/api/sessions/{sid}").json()["settings"]
        peak = _peak_now(client, sid)
        r = client.patch(url, json=change)
        assert r.status_code in (200, 409), r.text
        after = client.get(f"/api/sessions/{sid}").json()["settings"]
        assert _peak_now(client, sid) <= peak
        for name in ("torque_gain", "max_torque_Nm", "intent_gain_boost"):
            assert after[name] <= before[name]
        assert after["primary"] == before["primary"]
        clock.advance(1.0)  # past some of the rates: more of the changes get through
