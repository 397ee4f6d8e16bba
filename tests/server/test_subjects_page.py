"""What the subjects page relies on, through the real app and SQLite: trial names unique within a session
(refused with a clear error, the default names skipping taken ones), and the page's scripts served."""

from __future__ import annotations

from fastapi.testclient import TestClient

from tests.waiting import wait_until

SHORT = {"kind": "simulated", "protocol": [{"speed_m_s": 1.0, "incline_deg": 0.0, "strides": 200}], "rate_hz": 200}


def _session(client: TestClient) -> int:
    sid = client.post("/api/subjects", json={"code": "UNQ01", "leg_length_m": 0.9, "mass_kg": 70.0}).json()["id"]
    r = client.post("/api/sessions", json={"subject_id": sid, "source": SHORT})
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def _record(client: TestClient, sid: int, action: str, name: str = "") -> tuple[int, dict]:
    r = client.post(f"/api/sessions/{sid}/recording", json={"action": action, "name": name})
    return r.status_code, r.json()


def test_trial_names_are_unique_within_a_session(client: TestClient) -> None:
    sid = _session(client)
    runtime = client.app.state.ctx.manager.get(sid)  # type: ignore[attr-defined]
    wait_until(lambda: runtime.samples > 0, 15.0, "the session's first samples")
    assert _record(client, sid, "stop")[0] == 200  # "trial 1", recorded from the start
    code, t = _record(client, sid, "start", "fast walk")
    assert code == 200 and t["name"] == "fast walk"
    assert _record(client, sid, "stop")[0] == 200
    code, body = _record(client, sid, "start", "Fast Walk")  # names compare without case
    assert code == 409
    assert body["detail"] == f"session {sid} already has a trial named 'Fast Walk': choose another name"
    code, t = _record(client, sid, "start", "trial 3")
    assert code == 200 and t["name"] == "trial 3"
    assert _record(client, sid, "stop")[0] == 200
    code, t = _record(client, sid, "start")  # no name: the first free "trial N" (not "trial 3" again)
    assert code == 200 and t["name"] == "trial 4"
    code, again = _record(client, sid, "start", "trial 1")  # already recording: that trial, whatever the name
    assert code == 200 and again["id"] == t["id"]
    names = [x["name"] for x in client.get(f"/api/trials?session_id={sid}").json()]
    assert names == ["trial 1", "fast walk", "trial 3", "trial 4"]
    assert len({n.casefold() for n in names}) == len(names)
    client.post(f"/api/sessions/{sid}/stop")


def test_the_pages_scripts_are_served(client: TestClient) -> None:
    for name in ("subjects.js", "report.js", "report_export.js", "people_format.js", "upload.js", "people.css"):
        r = client.get(f"/{name}")
        assert r.status_code == 200 and len(r.content) > 200, name
    app = client.get("/app.js").text
    assert "mountSubjects" in app and "mountReport" in app
    assert 'href="#/subjects"' in client.get("/").text
