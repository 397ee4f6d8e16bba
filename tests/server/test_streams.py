"""Websockets against the real app: live browser streams and a live device."""

from __future__ import annotations

import itertools
import json
import time

import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from gaitscope.sessions.live.runtime import SUBSCRIBER_CAPACITY, Subscriber
from gaitscope.sessions.live.sources import DeviceBudget
from gaitscope.sessions.schema import MAX_FRAME_BYTES, MAX_NOTICE_ERRORS, GaitState
from gaitscope.sessions.synth.trials import replay_input, sensor_trial
from tests.device_tokens import device_path
from tests.waiting import wait_until

SIM = {
    "kind": "simulated",
    "protocol": [{"speed_m_s": 1.2, "incline_deg": 0.0, "strides": 200}],
    "rate_hz": 200,
}


def _session(client: TestClient, source: dict) -> int:
    sid = client.post("/api/subjects", json={"code": "W01", "leg_length_m": 0.88, "mass_kg": 64.0}).json()["id"]
    r = client.post("/api/sessions", json={"subject_id": sid, "source": source})
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def _states(ws, n: int, timeout: float = 10.0) -> tuple[list[dict], list[dict]]:
    states, other = [], []
    deadline = time.monotonic() + timeout
    while len(states) < n and time.monotonic() < deadline:
        msg = json.loads(ws.receive_text())
        if msg["type"] == "states":
            states += msg["states"]
            assert msg["decimation"] >= 1
        else:
            other.append(msg)
    return states, other


def test_browser_stream_full_and_decimated(client: TestClient) -> None:
    sid = _session(client, SIM)
    with client.websocket_connect(f"/ws/sessions/{sid}?max_rate_hz=0&batch_ms=20") as full:
        hello = json.loads(full.receive_text())
        assert hello["type"] == "hello" and hello["session"]["id"] == sid and hello["source_rate_hz"] == 200
        states, _ = _states(full, 200)
        t = [s["t"] for s in states]
        assert all(b > a for a, b in itertools.pairwise(t))
        assert all(abs((b - a) - 0.005) < 1e-6 for a, b in itertools.pairwise(t))  # every sample
        GaitState.model_validate(states[0])
    with client.websocket_connect(f"/ws/sessions/{sid}?max_rate_hz=50&batch_ms=50") as slow:
        json.loads(slow.receive_text())
        states, _ = _states(slow, 60)
        steps = {round(b["t"] - a["t"], 4) for a, b in itertools.pairwise(states)}
        assert steps == {0.02}  # every 4th of 200 Hz
        assert any(s["heel_strike"] for s in states)  # heel strikes survive decimation


def test_health_and_settings_reach_every_client(client: TestClient) -> None:
    sid = _session(client, SIM)
    runtime = client.app.state.ctx.manager.get(sid)  # type: ignore[attr-defined]
    wait_until(lambda: runtime.samples >= 400, 20.0, "2 s of samples")  # a full second of data behind the health
    with (
        client.websocket_connect(f"/ws/sessions/{sid}?max_rate_hz=20") as a,
        client.websocket_connect(f"/ws/sessions/{sid}?max_rate_hz=20") as b,
    ):
        json.loads(a.receive_text()), json.loads(b.receive_text())
        assert (
            client.patch(f"/api/sessions/{sid}/settings", json={"torque_gain": 1.3, "confirm": True}).status_code == 200
        )
        for ws in (a, b):
            other: list[dict] = []
            deadline = time.monotonic() + 10
            # the stream opens with the session's recent history (states): read on until the messages come
            while not {"settings", "event", "health"} <= {m["type"] for m in other} and time.monotonic() < deadline:
                other += _states(ws, 40, timeout=5)[1]
            types = {m["type"] for m in other}
            assert {"settings", "event", "health"} <= types
            health = next(m for m in other if m["type"] == "health")
            assert health["clients"] == 2 and 150 < health["rate_hz"] <= 210
            event = next(m for m in other if m["type"] == "event")["event"]
            assert (event["field"], event["before"], event["after"]) == ("torque_gain", 1.0, 1.3)


def test_unknown_session_is_refused(client: TestClient) -> None:
    with client.websocket_connect("/ws/sessions/99") as ws, pytest.raises(WebSocketDisconnect) as exc:
        ws.receive_text()
    assert exc.value.code == 4404 and "does not exist" in exc.value.reason


def test_live_device_gets_torque_back_and_browsers_see_it(client: TestClient) -> None:
    sid = _session(client, {"kind": "device", "rate_hz": 1000.0})
    sensors, _, _ = sensor_trial([(1.2, 0.0, 6)], rate_hz=100.0)
    frames = replay_input(sensors)
    with (
        client.websocket_connect(f"/ws/sessions/{sid}?max_rate_hz=0&batch_ms=0") as browser,
        client.websocket_connect(device_path(client, sid)) as device,
    ):
        json.loads(browser.receive_text())
        torques = []
        for k in range(300):
            frame = {
                "type": "frame",
                "seq": k,
                "t": 100.0 + float(frames.time_s[k]),
                "sent_ns": time.time_ns(),
            }
            frame |= {name: float(v[k]) for name, v in frames.signals.items()}
            device.send_text(json.dumps(frame))
            reply = json.loads(device.receive_text())
            assert reply["type"] == "torque" and reply["seq"] == k
            torques.append(reply["torque_Nm"])
        assert max(torques) > 5.0 and min(torques) == 0.0  # push-off assistance, none in swing
        last_t = 100.0 + float(frames.time_s[299])
        device.send_text(json.dumps({"type": "frame", "seq": 300, "t": last_t - 0.1}))  # a reordered frame
        notice = json.loads(device.receive_text())
        assert notice["kind"] == "order" and "does not follow" in notice["detail"]
        device.send_text('{"type": "frame", "seq": "x"}')
        assert json.loads(device.receive_text())["type"] == "error"
        states, _ = _states(browser, 300)
        assert [s["seq"] for s in states[:300]] == list(range(300))
        assert states[0]["t"] == 0.0 and states[-1]["sent_ns"] is not None
    health = client.app.state.ctx.manager.get(sid).health()  # type: ignore[attr-defined]
    assert health.dropped_input == 2 and health.samples == 300


def test_a_device_s_oversized_or_invalid_frames_get_short_notices_and_its_next_frame_a_torque(
    client: TestClient,
) -> None:
    sid = _session(client, {"kind": "device", "rate_hz": 200.0})
    with client.websocket_connect(device_path(client, sid)) as device:
        device.send_text('{"type": "frame", "seq": 0, "t": 0.0, "foot_angle_deg": [' + "0.5, " * 4000 + "0.5]}")
        notice = json.loads(device.receive_text())
        assert notice["kind"] == "too_large" and f"over the limit of {MAX_FRAME_BYTES}" in notice["detail"]
        device.send_text(json.dumps({"type": "frame", "seq": 0, "t": 0.0, **{f"x{i}": 0 for i in range(1000)}}))
        notice = json.loads(device.receive_text())
        assert notice["kind"] == "too_large" and "1003 keys" in notice["detail"]
        device.send_text(json.dumps({"type": "frame", "seq": 0, "t": 0.0, **{f"x{i}": 0.5 for i in range(70)}}))
        text = device.receive_text()
        notice = json.loads(text)
        assert notice["kind"] == "invalid" and notice["errors"] == 70 and len(notice["detail"]) == MAX_NOTICE_ERRORS
        assert len(text) < 1000 and "0.5" not in text  # never the input
        device.send_text(json.dumps({"type": "frame", "seq": 0, "t": 0.0, "foot_angle_deg": 1.0}))
        assert json.loads(device.receive_text())["type"] == "torque"


def test_a_device_held_back_for_refused_messages_is_disconnected(client: TestClient) -> None:
    sid = _session(client, {"kind": "device", "rate_hz": 1.0})  # 1.25 frames a second, a burst of 2.5
    runtime = client.app.state.ctx.manager.get(sid)  # type: ignore[attr-defined]
    runtime.source.budget = DeviceBudget(share=0.05, burst_s=0.01, close_after_s=0.3)  # 0.5 ms of credit
    with pytest.raises(WebSocketDisconnect) as exc, client.websocket_connect(device_path(client, sid)) as device:
        for k in range(20_000):  # over its rate: each one dropped unparsed, yet costing its read
            device.send_text(json.dumps({"type": "frame", "seq": k, "t": k * 0.001}))
        while True:
            reply = json.loads(device.receive_text())
            assert reply["type"] == "torque" or reply["kind"] == "rate"
    assert exc.value.code == 1008 and "refused messages over its share of the server (5%) for 0.3 s" in exc.value.reason


def test_second_device_and_device_on_simulated_session_are_refused(client: TestClient) -> None:
    sim = _session(client, SIM)
    r = client.post(f"/api/sessions/{sim}/device-tokens")  # no token for a session that takes no device
    assert r.status_code == 409 and "takes no device" in r.json()["detail"]
    with pytest.raises(WebSocketDisconnect) as exc, client.websocket_connect(f"/ws/devices/{sim}"):
        pass
    assert exc.value.code == 1008 and "no device token" in exc.value.reason


def test_a_slow_subscriber_loses_its_oldest_samples_and_counts_them() -> None:
    sub = Subscriber(decimation=1)
    state = GaitState.model_validate(
        dict(seq=0, t=0.0, phase=0.1, phase_rate=1.0, stride_length_m=1.2, incline_deg=0.0, torque_Nm=0.0,
             tbe_phase=0.1, heel_strike=False, backup_reset=False, foot_angle_deg=None, shank_angle_deg=None,
             thigh_angle_deg=None, foot_pred_deg=0.0, shank_pred_deg=0.0, recv_ns=0)
    )  # fmt: skip
    for k in range(SUBSCRIBER_CAPACITY + 25):
        sub.offer(state.model_copy(update={"seq": k}))
    assert sub.dropped == 25 and len(sub.pending) == SUBSCRIBER_CAPACITY
    assert sub.pending[0].seq == 25  # the newest are kept


def test_stopping_a_session_closes_its_streams(client: TestClient) -> None:
    sid = _session(client, SIM)
    with client.websocket_connect(f"/ws/sessions/{sid}?max_rate_hz=20") as ws:
        json.loads(ws.receive_text())
        assert client.post(f"/api/sessions/{sid}/stop").status_code == 200
        with pytest.raises(WebSocketDisconnect) as exc:
            for _ in range(200):
                ws.receive_text()
    assert exc.value.code == 1000 and "stopped" in exc.value.reason


def test_replay_session_plays_a_recorded_trial_faster(client: TestClient) -> None:
    sid = _session(client, SIM)
    runtime = client.app.state.ctx.manager.get(sid)  # type: ignore[attr-defined]
    wait_until(lambda: runtime.samples >= 500, 20.0, "2.5 s of samples")
    client.post(f"/api/sessions/{sid}/stop")
    trial = client.get(f"/api/trials?session_id={sid}").json()[0]
    subject_id = client.get(f"/api/sessions/{sid}").json()["subject_id"]
    source = {"kind": "replay", "trial_id": trial["id"], "speed": 4.0}
    replay = client.post("/api/sessions", json={"subject_id": subject_id, "source": source}).json()
    with client.websocket_connect(f"/ws/sessions/{replay['id']}?max_rate_hz=0&batch_ms=20") as ws:
        json.loads(ws.receive_text())
        start = time.monotonic()
        states, _ = _states(ws, 400)
        wall = time.monotonic() - start
    t = [s["t"] for s in states[:400]]
    assert t[0] < 0.5 and all(b > a for a, b in itertools.pairwise(t))  # from the start (give or take a connect)
    assert t[-1] - t[0] == pytest.approx(399 * 0.005, rel=1e-6)  # the recording's own 200 Hz
    assert wall < 0.9 * (t[-1] - t[0])  # played faster than real time (4x asked)
