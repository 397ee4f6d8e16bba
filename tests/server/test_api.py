"""The REST API against the real app, a real SQLite file and real MCAP recordings."""

from __future__ import annotations

from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from tests.server.apps import session, subject, wait_samples


def test_health_schema_and_openapi(client: TestClient) -> None:
    assert client.get("/api/health").json()["status"] == "ok"
    schemas = client.get("/api/schema").json()
    assert {"GaitState", "SensorFrame", "StreamBatch", "FoxgloveEvent", "SessionSettings"} <= set(schemas)
    assert "/api/sessions/{session_id}/settings" in client.get("/openapi.json").json()["paths"]


def test_subjects(client: TestClient) -> None:
    sid = subject(client)
    assert client.get(f"/api/subjects/{sid}").json()["code"] == "P01"
    r = client.post("/api/subjects", json={"code": "P01", "leg_length_m": 0.9, "mass_kg": 70.0})
    assert r.status_code == 409 and "P01" in r.json()["detail"]
    r = client.post("/api/subjects", json={"code": "P02", "leg_length_m": 5.0, "mass_kg": 70.0})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "leg_length_m"]
    assert client.get("/api/subjects/999").status_code == 404
    assert [s["code"] for s in client.get("/api/subjects").json()] == ["P01"]


def test_session_runs_records_and_reviews(client: TestClient, tmp_path: Path) -> None:
    s = session(client)
    assert s["state"] == "running"
    wait_samples(client, s["id"], 1.5)
    stopped = client.post(f"/api/sessions/{s['id']}/stop").json()
    assert stopped["state"] == "stopped" and stopped["stopped_utc"]
    trials = client.get(f"/api/trials?session_id={s['id']}").json()
    assert len(trials) == 1 and trials[0]["status"] == "finished" and trials[0]["samples"] >= 300
    tid = trials[0]["id"]
    series = client.get(f"/api/trials/{tid}/series?max_points=100").json()
    assert 10 <= len(series["t"]) <= 200 and all(0 <= p < 1 for p in series["phase"])
    window = client.get(f"/api/trials/{tid}/series?t0=0.5&t1=1.0&max_points=1000").json()
    assert 0.5 - 1e-9 <= min(window["t"]) and max(window["t"]) <= 1.0 + 1e-9 and len(window["t"]) > 50
    mcap = client.get(f"/api/trials/{tid}/download")
    assert mcap.status_code == 200 and mcap.content[:5] == b"\x89MCAP"
    # (the simulated walker feeds the intent filter: its detections are events too, tests/server/test_intent.py)
    kinds = [e["kind"] for e in client.get(f"/api/sessions/{s['id']}/events").json() if e["kind"] != "intent"]
    assert kinds == ["recording", "system", "recording"]  # started, soft start, stopped
    assert client.post(f"/api/sessions/{s['id']}/stop").status_code == 409


def test_settings_change_is_validated_rate_limited_and_recorded(client: TestClient) -> None:
    s = session(client)
    url = f"/api/sessions/{s['id']}/settings"
    r = client.patch(url, json={"torque_gain": 1.4, "actor": "local", "reason": "more push-off", "confirm": True})
    assert r.status_code == 200 and r.json()["settings"]["torque_gain"] == 1.4
    r = client.patch(url, json={"torque_gain": 1.8, "confirm": True})  # a second step right away breaks the rate limit
    assert r.status_code == 409 and "torque_gain" in r.json()["detail"]
    r = client.patch(url, json={"torque_gain": 2.5, "confirm": True})  # a step of 1.1 is never allowed at once
    assert r.status_code == 409 and "at most 0.5" in r.json()["detail"]
    r = client.patch(url, json={"max_torque_Nm": 500})
    assert r.status_code == 422
    assert client.get(f"/api/sessions/{s['id']}").json()["settings"]["torque_gain"] == 1.4
    events = [e for e in client.get(f"/api/sessions/{s['id']}/events").json() if e["kind"] == "setting"]
    assert len(events) == 1
    e = events[0]
    assert (e["field"], e["before"], e["after"], e["actor"]) == ("torque_gain", 1.0, 1.4, "local")
    assert "more push-off" in e["text"]
    runtime = client.app.state.ctx.manager.get(s["id"])  # type: ignore[attr-defined]
    assert runtime.estimator.settings.torque_gain == 1.4  # applied to the estimator, not just stored


def test_annotations_and_recording_controls(client: TestClient) -> None:
    s = session(client)
    r = client.post(f"/api/sessions/{s['id']}/annotations", json={"text": "subject reports knee discomfort"})
    assert r.status_code == 201 and r.json()["kind"] == "annotation"
    assert client.post(f"/api/sessions/{s['id']}/annotations", json={"text": ""}).status_code == 422
    first = client.post(f"/api/sessions/{s['id']}/recording", json={"action": "stop"}).json()
    assert first["status"] == "finished"
    assert client.post(f"/api/sessions/{s['id']}/recording", json={"action": "stop"}).status_code == 409
    second = client.post(f"/api/sessions/{s['id']}/recording", json={"action": "start", "name": "fast walk"}).json()
    assert second["name"] == "fast walk" and second["status"] == "recording"
    assert client.get(f"/api/trials/{second['id']}/series").status_code == 409  # still recording


def test_rerun_with_other_settings(client: TestClient) -> None:
    s = session(client)
    wait_samples(client, s["id"], 2.0)
    client.post(f"/api/sessions/{s['id']}/stop")
    tid = client.get(f"/api/trials?session_id={s['id']}").json()[0]["id"]
    base = client.get(f"/api/trials/{tid}/series?max_points=5000").json()
    settings = {"torque_gain": 0.2}  # within the first 2 s the soft start caps any gain above 1 alike
    again = client.post(f"/api/trials/{tid}/rerun?max_points=5000", json={"settings": settings}).json()
    assert len(again["t"]) == len(base["t"]) and again["t"][:50] == pytest.approx(base["t"][:50])
    assert 0 < max(again["torque_Nm"]) < 0.5 * max(base["torque_Nm"])


def test_unknown_things_are_404(client: TestClient) -> None:
    assert client.get("/api/sessions/42").status_code == 404
    assert client.get("/api/trials/42").status_code == 404
    assert client.patch("/api/sessions/42/settings", json={"torque_gain": 1.1}).status_code == 404
    r = client.post("/api/sessions", json={"subject_id": 42})
    assert r.status_code == 404 and "42" in r.json()["detail"]


def test_models_are_listed_with_provenance(client: TestClient) -> None:
    models = client.get("/api/models").json()
    assert models[0]["name"] == "default" and models[0]["provenance"]["source"] == "default-cohort"


def test_a_device_that_declares_its_channels_gets_the_stack_they_feed_and_a_refusal_naming_what_it_lacks(
    client: TestClient,
) -> None:
    sid = subject(client, "DEV1")
    source = {"kind": "device", "rate_hz": 100, "channels": ["foot_angle_deg", "foot_vel_dps", "shank_angle_deg"]}
    r = client.post("/api/sessions", json={"subject_id": sid, "source": source})
    assert r.status_code == 201, r.text
    runtime = client.app.state.ctx.manager.get(r.json()["id"])  # type: ignore[attr-defined]
    assert runtime.estimator.stack.names == ("hs_detector", "phase_ekf", "tbe")
    client.post(f"/api/sessions/{r.json()['id']}/stop")
    asked = {"estimators": ["phase_ekf", "fp_avg"]}
    r = client.post("/api/sessions", json={"subject_id": sid, "source": source, "settings": asked})
    assert r.status_code == 409 and "fp_avg needs thigh_angle_deg" in r.json()["detail"], r.text
    bad = {**source, "channels": ["foot_angle_deg", "warp_drive"]}
    r = client.post("/api/sessions", json={"subject_id": sid, "source": bad})
    assert r.status_code == 422 and "unknown channel warp_drive" in r.text
