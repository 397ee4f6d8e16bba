"""The live view's server side: the last 30 s sent to a newly connected browser, and undoing the last change."""

from __future__ import annotations

import itertools
import json
import time

from fastapi.testclient import TestClient

from gaitscope.sessions.live.subscribers import HISTORY_S, attach_history
from tests.waiting import ShiftedClock, wait_until

SIM = {"kind": "simulated", "protocol": [{"speed_m_s": 1.2, "incline_deg": 0.0, "strides": 200}], "rate_hz": 200}


def _session(client: TestClient) -> int:
    sid = client.post("/api/subjects", json={"code": "H01", "leg_length_m": 0.88, "mass_kg": 64.0}).json()["id"]
    r = client.post("/api/sessions", json={"subject_id": sid, "source": SIM})
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def _wait_samples(client: TestClient, sid: int, n: int) -> None:
    runtime = client.app.state.ctx.manager.get(sid)  # type: ignore[attr-defined]
    wait_until(lambda: runtime.samples >= n, 20.0, f"{n} samples of session {sid}")


def _messages(ws, n_states: int) -> list[dict]:
    out, count = [], 0
    deadline = time.monotonic() + 10
    while count < n_states and time.monotonic() < deadline:
        msg = json.loads(ws.receive_text())
        out.append(msg)
        count += len(msg.get("states", []))
    return out


def test_a_new_browser_first_gets_the_recent_history_then_live_states_without_a_gap(client: TestClient) -> None:
    sid = _session(client)
    with client.websocket_connect(f"/ws/sessions/{sid}?max_rate_hz=60") as first:
        assert json.loads(first.receive_text())["type"] == "hello"
        start = client.app.state.ctx.manager.get(sid).samples  # type: ignore[attr-defined]
        _wait_samples(client, sid, start + 400)  # 2 s of the session while a browser watches
        with client.websocket_connect(f"/ws/sessions/{sid}?max_rate_hz=60&batch_ms=20") as second:
            hello = json.loads(second.receive_text())
            assert hello["type"] == "hello"
            history = json.loads(second.receive_text())  # the very next message: the history
            assert history["type"] == "states" and history["decimation"] == 4  # 200 Hz kept at 50 Hz
            assert len(history["states"]) >= 95  # ~2 s at 50 Hz
            assert {"phase_ekf"} <= set(history["estimators"])
            assert len(history["estimators"]["phase_ekf"]["columns"]["phase"]) == len(history["states"])
            later = _messages(second, 60)
            states = history["states"] + [s for m in later if m["type"] == "states" for s in m["states"]]
            steps = {round(b["t"] - a["t"], 4) for a, b in itertools.pairwise(states)}
            assert steps == {0.02}  # history and live meet without a gap or an overlap
            health = [m for m in later if m["type"] == "health"]
            assert not health or health[-1]["clients"] == 2  # the history is no client


def test_the_history_is_at_most_30_s(client: TestClient) -> None:
    sid = _session(client)
    history = attach_history(client.app.state.ctx.manager.get(sid))  # type: ignore[attr-defined]
    _wait_samples(client, sid, 200)
    assert history.seconds == HISTORY_S == 30.0
    assert history.pending.maxlen is not None and history.pending.maxlen <= 30 * 60 + 64


def _event_texts(client: TestClient, sid: int) -> list[dict]:
    return [e for e in client.get(f"/api/sessions/{sid}/events").json() if e["kind"] == "setting"]


def test_undo_sets_back_the_last_change_and_is_logged(client: TestClient) -> None:
    clock = ShiftedClock()
    client.app.state.ctx.manager.clock = clock  # type: ignore[attr-defined]  # the session's rate limits read it
    sid = _session(client)
    _wait_samples(client, sid, 50)
    r = client.post(f"/api/sessions/{sid}/settings/undo", json={"actor": "clinician"})
    assert r.status_code == 409 and r.json()["detail"] == "nothing to undo: no setting has been changed in this session"
    r = client.patch(
        f"/api/sessions/{sid}/settings",
        json={"torque_gain": 1.3, "max_torque_Nm": 35, "actor": "experimenter", "confirm": True},
    )
    assert r.status_code == 200, r.text
    r = client.post(f"/api/sessions/{sid}/settings/undo", json={"actor": "clinician"})
    assert r.status_code == 200, r.text  # an undo that lowers the torque is never held back
    assert r.json()["settings"]["torque_gain"] == 1.0 and r.json()["settings"]["max_torque_Nm"] == 30.0
    events = _event_texts(client, sid)
    assert [(e["field"], e["before"], e["after"], e["actor"]) for e in events[-2:]] == [
        ("torque_gain", 1.3, 1.0, "local"),
        ("max_torque_Nm", 35.0, 30.0, "local"),
    ]
    assert "(undo of Torque gain 1× → 1.3×, Maximum torque 30 N·m → 35 N·m by local)" in events[-2]["text"]
    r = client.post(f"/api/sessions/{sid}/settings/undo", json={"actor": "clinician", "confirm": True})
    assert r.status_code == 409  # undoing the undo raises the torque: the undo was a change too, its own 0.6 s
    assert "torque_gain changed" in r.json()["detail"]
    clock.advance(1.5)
    r = client.post(f"/api/sessions/{sid}/settings/undo", json={"actor": "clinician", "confirm": True})
    assert r.status_code == 409 and r.json()["detail"]["reason"] == "too_soon"  # 3 s after the last raise
    clock.advance(1.5)
    r = client.post(f"/api/sessions/{sid}/settings/undo", json={"actor": "clinician"})
    assert r.status_code == 409 and r.json()["detail"]["reason"] == "confirm"  # it raises the torque: it asks
    r = client.post(f"/api/sessions/{sid}/settings/undo", json={"actor": "clinician", "confirm": True})
    assert r.status_code == 200 and r.json()["settings"]["torque_gain"] == 1.3


def test_undo_refusals_say_why(client: TestClient) -> None:
    assert client.post("/api/sessions/999/settings/undo", json={}).status_code == 404
    r = client.post("/api/sessions/999/settings/undo", json={"actor": ""})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "actor"]
    sid = _session(client)
    assert client.post(f"/api/sessions/{sid}/stop").status_code == 200
    r = client.post(f"/api/sessions/{sid}/settings/undo", json={})
    assert r.status_code == 409 and "is not running" in r.json()["detail"]
