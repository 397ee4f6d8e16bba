"""IMU mounting calibration through the real app: a device session fed over the real websocket. Standing
still, each front end takes its sensor's pitch offset and gyro bias (stored as the subject's current
calibration, logged, recorded in the MCAP, applied by the subject's next session and by a re-run);
walking, it is refused with each sensor's reason and nothing changes."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from starlette.testclient import WebSocketTestSession

from gaitscope.estimators.imu_frontend import ImuFrontEnd
from gaitscope.sessions.formats.mcap_io import read_events, read_messages
from tests.device_tokens import device_path
from tests.walks import IMU_CHANNELS, MOUNTING, imu_standing, imu_walking


def _session(client: TestClient, code: str = "C01", subject_id: int | None = None) -> tuple[int, int]:
    if subject_id is None:
        r = client.post("/api/subjects", json={"code": code, "leg_length_m": 0.9, "mass_kg": 70.0})
        assert r.status_code == 201, r.text
        subject_id = int(r.json()["id"])
    source = {"kind": "device", "rate_hz": 1000.0, "channels": IMU_CHANNELS}  # as fast as the socket takes them
    r = client.post("/api/sessions", json={"subject_id": subject_id, "source": source})
    assert r.status_code == 201, r.text
    return subject_id, int(r.json()["id"])


def _send(device: WebSocketTestSession, frames: list[dict[str, Any]], seq0: int = 0) -> None:
    for k, frame in enumerate(frames):
        device.send_text(json.dumps({**frame, "seq": seq0 + k}))
        assert json.loads(device.receive_text())["type"] == "torque"


def _front_ends(client: TestClient, sid: int) -> dict[str, ImuFrontEnd]:
    runtime = client.app.state.ctx.manager.get(sid)  # type: ignore[attr-defined]
    return {e.name: e for e in runtime.estimator.stack.estimators if isinstance(e, ImuFrontEnd)}


def test_standing_still_calibrates_stores_logs_records_and_is_applied_again(client: TestClient) -> None:
    subject_id, sid = _session(client)
    assert client.get(f"/api/sessions/{sid}/imu-calibration").json()["state"] == "idle"
    with client.websocket_connect(device_path(client, sid)) as device:
        _send(device, imu_standing(0.0, 1.0))
        body = {"duration_s": 2, "actor": "local", "note": "upright"}
        r = client.post(f"/api/sessions/{sid}/imu-calibration", json=body)
        assert r.status_code == 202, r.text
        assert r.json()["state"] == "collecting" and r.json()["segments"] == ["foot", "shank"]
        assert client.post(f"/api/sessions/{sid}/imu-calibration", json={}).status_code == 409  # one at a time
        _send(device, imu_standing(1.0, 1.0, seed=1), 100)
        status = client.get(f"/api/sessions/{sid}/imu-calibration").json()
        assert status["state"] == "collecting" and 0.45 < status["progress"] < 0.55
        _send(device, imu_standing(2.0, 4.0, seed=2), 200)  # the period ends at 3.0 s; then 3 s calibrated
        status = client.get(f"/api/sessions/{sid}/imu-calibration").json()
        ends = _front_ends(client, sid)
    assert status["state"] == "done" and status["progress"] == 1.0
    result = status["result"]
    assert result["ok"] and result["reason"] == "" and result["created_by"] == "local" and result["note"] == "upright"
    assert status["applied"] == result
    for s in result["sensors"]:  # each sensor's mounting, found and applied to its front end
        offset, bias = MOUNTING[s["segment"]]
        assert s["pitch_offset_deg"] == pytest.approx(offset, abs=0.05)
        assert s["gyro_bias_dps"] == pytest.approx(bias, abs=0.05)
        config = ends[f"imu_{s['segment']}"].config
        assert config.pitch_offset_deg == s["pitch_offset_deg"]
        assert (config.gyro_bias_x_dps, config.gyro_bias_y_dps, config.gyro_bias_z_dps) == tuple(s["gyro_bias_dps"])
    assert client.get(f"/api/subjects/{subject_id}/imu-calibrations").json() == [result]  # the current one
    event = next(e for e in client.get(f"/api/sessions/{sid}/events").json() if e["field"] == "imu_calibration")
    assert event["kind"] == "system" and event["actor"] == "local" and event["t"] == pytest.approx(3.0)
    assert event["text"].startswith(f"IMU calibration {result['id']} applied: imu_foot pitch offset -5.0 deg")
    assert client.post(f"/api/sessions/{sid}/stop").status_code == 200

    (trial,) = client.get(f"/api/trials?session_id={sid}").json()
    path = client.app.state.ctx.settings.data_dir / trial["path"]  # type: ignore[attr-defined]
    (recorded,) = [m for _, _, m in read_messages(path, ["/imu_calibration"])]
    assert recorded == result
    assert any(e.get("field") == "imu_calibration" and e["text"] == event["text"] for e in read_events(path))
    # a re-run applies the recorded calibration where it was made, as it did live: before, the shank reads its
    # 8 deg mounting plus what the uncorrected gyro bias holds it off by (bias / k_p = 1.2 / 0.5 deg), after,
    # upright (0) once the filter has converged (time constant 1 / k_p = 2 s)
    r = client.post(f"/api/trials/{trial['id']}/rerun?max_points=20000", json={})
    assert r.status_code == 200, r.text
    t, shank = np.array(r.json()["t"]), np.array(r.json()["imu_shank.shank_angle_deg"], dtype=float)
    live = np.array([v["values"]["shank_angle_deg"] for _, _, v in read_messages(path, ["/estimators/imu_shank"])])
    np.testing.assert_allclose(shank, live, atol=1e-9)
    before = shank[(t > 2.0) & (t <= 3.0)]
    assert 8.0 < before.min() and before.max() < 8.0 + 2.4 and abs(shank[t > 3.0][0]) < 2.4
    assert np.abs(shank[t > 5.5]).max() < 0.5

    # the subject's next session starts with it
    _, sid2 = _session(client, subject_id=subject_id)
    ends = _front_ends(client, sid2)
    assert ends["imu_shank"].config.pitch_offset_deg == pytest.approx(8.0, abs=0.05)
    assert client.get(f"/api/sessions/{sid2}/imu-calibration").json()["applied"] == result
    (started,) = [e for e in client.get(f"/api/sessions/{sid2}/events").json() if e["field"] == "imu_calibration"]
    assert started["text"].startswith(f"the subject's IMU calibration {result['id']} (")
    assert client.post(f"/api/sessions/{sid2}/stop").status_code == 200
    (trial2,) = client.get(f"/api/trials?session_id={sid2}").json()
    path2 = client.app.state.ctx.settings.data_dir / trial2["path"]  # type: ignore[attr-defined]
    assert [m for _, _, m in read_messages(path2, ["/imu_calibration"])] == [result]


def test_walking_is_refused_with_each_sensors_reason_and_nothing_applied(client: TestClient) -> None:
    subject_id, sid = _session(client)
    with client.websocket_connect(device_path(client, sid)) as device:
        r = client.post(f"/api/sessions/{sid}/imu-calibration", json={"duration_s": 2})
        assert r.status_code == 202, r.text
        _send(device, imu_walking(0.0))
        status = client.get(f"/api/sessions/{sid}/imu-calibration").json()
        ends = _front_ends(client, sid)
    assert status["state"] == "refused" and status["applied"] is None
    result = status["result"]
    assert not result["ok"] and result["id"] is None
    for seg in ("foot", "shank"):
        assert f"imu_{seg}: not still: the gyro moved " in result["reason"]
        assert ends[f"imu_{seg}"].config.pitch_offset_deg == 0.0 and ends[f"imu_{seg}"].config.gyro_bias_z_dps == 0.0
    assert result["reason"].count("stand still and try again") == 2
    assert all(not s["ok"] and s["gyro_motion_dps"] > 10 for s in result["sensors"])
    assert client.get(f"/api/subjects/{subject_id}/imu-calibrations").json() == []
    (event,) = [e for e in client.get(f"/api/sessions/{sid}/events").json() if e["field"] == "imu_calibration"]
    assert event["text"] == f"IMU calibration refused: {result['reason']}"
    assert client.post(f"/api/sessions/{sid}/stop").status_code == 200
    (trial,) = client.get(f"/api/trials?session_id={sid}").json()
    path = client.app.state.ctx.settings.data_dir / trial["path"]  # type: ignore[attr-defined]
    assert list(read_messages(path, ["/imu_calibration"])) == []


def test_a_session_without_imus_or_not_running_is_409_and_bad_bodies_422(client: TestClient) -> None:
    subject_id, sid = _session(client)
    for body in ({"duration_s": 1.9}, {"duration_s": 30.5}, {"duration_s": "long"}, {"posture": "upright"}):
        r = client.post(f"/api/sessions/{sid}/imu-calibration", json=body)
        assert r.status_code == 422, (body, r.text)
    assert client.post(f"/api/sessions/{sid}/stop").status_code == 200
    r = client.post(f"/api/sessions/{sid}/imu-calibration", json={})
    assert r.status_code == 409 and "is not running" in r.json()["detail"]
    assert client.post("/api/sessions/999/imu-calibration", json={}).status_code == 404

    source = {"kind": "device", "channels": ["foot_angle_deg", "shank_angle_deg"]}
    r = client.post("/api/sessions", json={"subject_id": subject_id, "source": source})
    assert r.status_code == 201, r.text
    no_imu = r.json()["id"]
    r = client.post(f"/api/sessions/{no_imu}/imu-calibration", json={})
    assert r.status_code == 409
    assert r.json()["detail"].startswith(f"session {no_imu} has no IMU to calibrate: its stack runs no IMU front end")
    assert client.get(f"/api/sessions/{no_imu}/imu-calibration").json()["segments"] == []
