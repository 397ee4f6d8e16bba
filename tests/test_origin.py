"""Requests that change state from another site are refused; same-site and non-browser ones are not."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

EVIL = {"origin": "http://evil.example"}


def _session(client: TestClient) -> int:
    sid = client.post("/api/subjects", json={"code": "O1", "leg_length_m": 0.9, "mass_kg": 70}).json()["id"]
    return int(client.post("/api/sessions", json={"subject_id": sid, "source": {"kind": "device"}}).json()["id"])


def test_cross_origin_writes_are_refused(client: TestClient) -> None:
    sid = _session(client)
    r = client.post(f"/api/sessions/{sid}/stop", headers=EVIL)
    assert r.status_code == 403 and r.json()["detail"] == "cross-origin request from http://evil.example refused"
    assert client.get(f"/api/sessions/{sid}").json()["state"] == "running"
    assert client.get(f"/api/sessions/{sid}", headers=EVIL).status_code == 200  # reading is harmless here


def test_cross_origin_websockets_are_refused(client: TestClient) -> None:
    sid = _session(client)
    with pytest.raises(WebSocketDisconnect) as exc, client.websocket_connect(f"/ws/devices/{sid}", headers=EVIL):
        pass
    assert exc.value.code == 1008


def test_same_origin_and_devices_pass(client: TestClient) -> None:
    sid = _session(client)
    same = {"origin": "http://testserver"}
    assert client.patch(f"/api/sessions/{sid}/settings", json={"torque_gain": 1.2}, headers=same).status_code == 200
    with client.websocket_connect(f"/ws/devices/{sid}") as ws:  # a device sends no Origin
        ws.send_json({"type": "frame", "seq": 0, "t": 0.0, "foot_angle_deg": 5.0})
        assert ws.receive_json()["type"] == "torque"
    assert client.post(f"/api/sessions/{sid}/stop", headers=same).status_code == 200
