"""Accounts end to end on the real app with accounts on: logging in and out, the lockout, a password change,
the event log's "who" from the login, the experimenters' assistance limits, device tokens, and
``gaitscope user add``. Real SQLite files, real argon2 hashes, real websockets."""

from __future__ import annotations

import io
import json
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from gaitscope.server.app import create_app
from gaitscope.server.auth import COOKIE, CSRF_HEADER
from gaitscope.server.cli import main
from gaitscope.sessions import schema
from tests.server.apps import PASSWORD, SHORT, auth_settings, login, wait_samples


@pytest.fixture
def app(tmp_path: Path) -> Iterator[TestClient]:
    with TestClient(create_app(auth_settings(tmp_path, lockout_after=3))) as c:
        accounts = c.app.state.ctx.accounts  # type: ignore[attr-defined]
        for name, role in (("ada", "admin"), ("cleo", "clinician"), ("eve", "experimenter"), ("vic", "viewer")):
            accounts.add_user(schema.UserCreate(name=name, role=role, password=PASSWORD), by="test")
        yield c


def _subject_and_session(c: TestClient, headers: dict[str, str], source: dict[str, object]) -> tuple[int, int]:
    subject = c.post("/api/subjects", json={"code": "S1", "leg_length_m": 0.9, "mass_kg": 70}, headers=headers)
    assert subject.status_code == 201, subject.text
    body = {"subject_id": subject.json()["id"], "source": source}
    session = c.post("/api/sessions", json=body, headers=headers)
    assert session.status_code == 201, session.text
    return subject.json()["id"], session.json()["id"]


def test_login_me_logout(app: TestClient) -> None:
    assert app.get("/api/auth/me").status_code == 401
    r = app.post("/api/auth/login", json={"name": "cleo", "password": PASSWORD})
    assert r.status_code == 200
    me = r.json()
    assert (me["name"], me["role"], me["accounts"]) == ("cleo", "clinician", True) and me["csrf_token"]
    cookie = r.headers["set-cookie"]
    assert "HttpOnly" in cookie and "SameSite=strict" in cookie and "Secure" not in cookie  # no TLS here
    assert app.get("/api/auth/me").json()["name"] == "cleo"
    assert app.post("/api/auth/logout").status_code == 403  # a state change: the CSRF token is needed
    assert app.post("/api/auth/logout", headers={CSRF_HEADER: me["csrf_token"]}).status_code == 204
    assert app.cookies.get(COOKIE) is None
    # the login ended on the server, not only in this browser: its old cookie no longer works
    app.cookies.set(COOKIE, cookie.split(";")[0].split("=", 1)[1])
    assert app.get("/api/auth/me").status_code == 401


def test_a_wrong_password_is_refused_counted_and_slowed_not_locked(app: TestClient) -> None:
    for name in ("cleo", "nobody"):  # an unknown name gets the same answer
        r = app.post("/api/auth/login", json={"name": name, "password": "not it at all"})
        assert (r.status_code, r.json()["detail"]) == (401, "wrong name or password")
    for _ in range(2):
        app.post("/api/auth/login", json={"name": "cleo", "password": "not it at all"})
    r = app.post("/api/auth/login", json={"name": "cleo", "password": PASSWORD})
    assert r.status_code == 401 and r.json()["detail"].startswith("locked after too many failed logins")  # held back
    admin = login(app, "ada")  # ada is not held back by cleo's failures
    assert app.get("/api/users", headers=admin).json()[1]["failed_logins"] == 3  # cleo's, shown to admins
    assert app.patch("/api/users/cleo", json={"unlock": True}, headers=admin).status_code == 200
    assert app.post("/api/auth/login", json={"name": "cleo", "password": PASSWORD}).status_code == 200
    failed = app.get("/api/audit", params={"action": "login.failed"}, headers=admin).json()
    assert len(failed) >= 4 and {e["user"] for e in failed} == {"cleo", "nobody"}
    assert any("held back" in e["detail"] for e in failed)  # the audit trail tells what the answer does not


def test_a_disabled_account_cannot_log_in_and_its_logins_end(app: TestClient) -> None:
    vic = login(app, "vic")
    admin = login(app, "ada")
    assert app.patch("/api/users/vic", json={"disabled": True}, headers=admin).status_code == 200
    assert app.get("/api/subjects", headers={"cookie": vic["cookie"]}).status_code == 401
    r = app.post("/api/auth/login", json={"name": "vic", "password": PASSWORD})
    assert r.status_code == 401 and "disabled" in r.json()["detail"]
    r = app.patch("/api/users/ada", json={"role": "viewer"}, headers=admin)
    assert r.status_code == 409 and "last admin" in r.json()["detail"]


def test_a_password_change_ends_every_login(app: TestClient) -> None:
    first, second = login(app, "eve"), login(app, "eve")
    bad = app.post("/api/auth/password", json={"current": "wrong one!!", "new": "a new good password"}, headers=first)
    assert bad.status_code == 403
    short = app.post("/api/auth/password", json={"current": PASSWORD, "new": "short"}, headers=first)
    assert short.status_code == 422
    ok = app.post("/api/auth/password", json={"current": PASSWORD, "new": "a new good password"}, headers=first)
    assert ok.status_code == 204
    for h in (first, second):
        assert app.get("/api/auth/me", headers={"cookie": h["cookie"]}).status_code == 401
    assert app.post("/api/auth/login", json={"name": "eve", "password": PASSWORD}).status_code == 401
    login(app, "eve", "a new good password")


def test_who_is_the_login_never_the_body(app: TestClient) -> None:
    cleo = login(app, "cleo")
    _, sid = _subject_and_session(app, cleo, {"kind": "simulated"})
    r = app.post(f"/api/sessions/{sid}/annotations", json={"text": "step", "actor": "mallory"}, headers=cleo)
    assert r.status_code == 201 and r.json()["actor"] == "cleo"
    r = app.patch(
        f"/api/sessions/{sid}/settings", json={"torque_gain": 1.1, "actor": "mallory", "confirm": True}, headers=cleo
    )
    assert r.status_code == 200
    events = app.get(f"/api/sessions/{sid}/events", headers=cleo).json()
    assert {e["actor"] for e in events if e["kind"] in ("annotation", "setting")} == {"cleo"}
    audit = app.get("/api/audit", params={"action": "settings.change"}, headers=login(app, "ada")).json()
    assert [(e["user"], e["role"], json.loads(e["before"]), json.loads(e["after"])) for e in audit] == [
        ("cleo", "clinician", {"torque_gain": 1.0}, {"torque_gain": 1.1, "confirm": True})  # a confirmed raise
    ]


def test_an_experimenter_changes_assistance_only_within_the_clinicians_limits(app: TestClient) -> None:
    cleo, eve = login(app, "cleo"), login(app, "eve")
    subject, sid = _subject_and_session(app, cleo, {"kind": "simulated"})
    r = app.patch(f"/api/sessions/{sid}/settings", json={"torque_gain": 1.1, "confirm": True}, headers=eve)
    assert r.status_code == 403 and "no assistance limits" in r.json()["detail"]
    noise = app.patch(f"/api/sessions/{sid}/settings", json={"measurement_noise_scale": 2.0}, headers=eve)
    assert noise.status_code == 200  # estimator tuning is the experimenter's
    limits = {"torque_gain": 1.2, "max_torque_Nm": 25.0, "intent_gain_boost": 0.1}
    assert app.put(f"/api/subjects/{subject}/assistance-limits", json=limits, headers=eve).status_code == 403
    assert app.put(f"/api/subjects/{subject}/assistance-limits", json=limits, headers=cleo).status_code == 200
    over = app.patch(f"/api/sessions/{sid}/settings", json={"torque_gain": 1.3, "confirm": True}, headers=eve)
    assert over.status_code == 403 and "torque_gain 1.3 over the limit of 1.2" in over.json()["detail"]
    assert app.get(f"/api/sessions/{sid}", headers=eve).json()["settings"]["torque_gain"] == 1.0  # unchanged
    r = app.patch(f"/api/sessions/{sid}/settings", json={"primary": "tbe", "confirm": True}, headers=eve)
    assert r.status_code == 403 and "estimator driving the torque" in r.json()["detail"]
    assert (
        app.patch(f"/api/sessions/{sid}/settings", json={"torque_gain": 1.15, "confirm": True}, headers=eve).status_code
        == 200
    )
    refused = app.get("/api/audit", params={"outcome": "refused"}, headers=login(app, "ada")).json()
    assert any(e["user"] == "eve" and "403" in e["detail"] for e in refused)


def test_device_tokens(app: TestClient) -> None:
    eve, vic = login(app, "eve"), login(app, "vic")
    _, sid = _subject_and_session(app, login(app, "cleo"), {"kind": "device", "rate_hz": 100.0})
    assert app.post(f"/api/sessions/{sid}/device-tokens", headers=vic).status_code == 403
    issued = app.post(f"/api/sessions/{sid}/device-tokens", headers=eve).json()
    token = issued["token"]
    assert len(token) >= 40 and issued["prefix"] == token[:6]
    listed = app.get(f"/api/sessions/{sid}/device-tokens", headers=vic).json()
    assert [t["token"] for t in listed] == [None]  # shown once: never listed
    frame = {"type": "frame", "seq": 0, "t": 0.0, "foot_angle_deg": 5.0}
    for refused, why in ((f"/ws/devices/{sid}", "no device token"), (f"/ws/devices/{sid}?token=x{token}", "wrong")):
        with pytest.raises(WebSocketDisconnect) as exc, app.websocket_connect(refused):
            pass
        assert exc.value.code == 1008 and why in exc.value.reason
    with app.websocket_connect(f"/ws/devices/{sid}", headers={"authorization": f"Bearer {token}"}) as ws:
        ws.send_json(frame)
        assert ws.receive_json()["type"] == "torque"
        r = app.delete(f"/api/sessions/{sid}/device-tokens/{issued['id']}", headers=eve)
        assert r.status_code == 200 and r.json()["revoked_by"] == "eve"
        ws.send_json({**frame, "seq": 1, "t": 0.01})
        with pytest.raises(WebSocketDisconnect) as exc:
            ws.receive_json()
        assert exc.value.code == 1008 and "revoked" in exc.value.reason
    with pytest.raises(WebSocketDisconnect) as exc, app.websocket_connect(f"/ws/devices/{sid}?token={token}"):
        pass
    assert exc.value.code == 1008 and "revoked" in exc.value.reason


def test_user_add_from_the_command_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    data = tmp_path / "data"
    monkeypatch.setattr("sys.stdin", io.StringIO("a long enough password\n"))
    assert main(["user", "--data-dir", str(data), "add", "boss", "--role", "admin", "--password-stdin"]) == 0
    monkeypatch.setattr("sys.stdin", io.StringIO("short\n"))
    assert main(["user", "--data-dir", str(data), "add", "b2", "--role", "admin", "--password-stdin"]) == 2
    monkeypatch.setattr("sys.stdin", io.StringIO("a long enough password\n"))
    assert main(["user", "--data-dir", str(data), "add", "boss", "--role", "viewer", "--password-stdin"]) == 2
    with TestClient(create_app(auth_settings(tmp_path))) as c:
        headers = login(c, "boss", "a long enough password")
        assert c.get("/api/users", headers=headers).json()[0]["role"] == "admin"


def test_only_its_author_deletes_a_review_note(app: TestClient) -> None:
    cleo, eve = login(app, "cleo"), login(app, "eve")
    _, sid = _subject_and_session(app, cleo, SHORT)
    wait_samples(app, sid, 2.0)
    assert app.post(f"/api/sessions/{sid}/stop", headers=cleo).status_code == 200
    trial = app.get("/api/trials", params={"session_id": sid}, headers=cleo).json()[0]
    url = f"/api/trials/{trial['id']}/annotations"
    note = app.post(url, json={"t": 1.0, "text": "toe catch"}, headers=eve).json()
    assert note["actor"] == "eve"
    r = app.delete(f"{url}/{note['id']}", headers=cleo)
    assert r.status_code == 403 and "written by eve" in r.json()["detail"]
    assert app.delete(f"{url}/{note['id']}", headers=eve).status_code == 204
