"""Every state change is audited (issue #21): the app's routes that are not reads are enumerated, each must be in
:data:`AUDITED` (with the action it writes) or in :data:`EXEMPT` (with the reason it changes nothing worth an
entry), and each audited one is driven, successfully, through the real app with accounts on, on a real SQLite
file: the entry must be there, with the caller's name and the target.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.routing import APIRoute
from fastapi.testclient import TestClient

from gaitscope.server.app import create_app
from gaitscope.server.auth import CSRF_HEADER
from gaitscope.server.origin import SAFE_METHODS
from gaitscope.server.settings import Settings
from gaitscope.sessions import schema
from gaitscope.sessions.gp_models import GP_EKF
from tests.server.apps import PASSWORD, app_routes, recorded
from tests.waiting import ShiftedClock
from tests.walks import IMU_CHANNELS, replay_csv, walk_frames

#: (method, route) -> the action its entry has.
AUDITED: dict[tuple[str, str], str] = {
    ("POST", "/api/auth/login"): "login",
    ("POST", "/api/auth/logout"): "logout",
    ("POST", "/api/auth/password"): "password.change",
    ("POST", "/api/users"): "user.add",
    ("PATCH", "/api/users/{name}"): "user.change",
    ("POST", "/api/subjects"): "subject.create",
    ("PUT", "/api/subjects/{subject_id}/assistance-limits"): "limits.set",
    ("POST", "/api/subjects/{subject_id}/fingerprints"): "fingerprint.calibrate",
    ("PUT", "/api/subjects/{subject_id}/intent-model"): "intent_model.set",
    ("DELETE", "/api/subjects/{subject_id}/intent-model"): "intent_model.reset",
    ("POST", "/api/subjects/{subject_id}/fingerprints/{personalization_id}/promote"): "fingerprint.promote",
    ("POST", "/api/subjects/{subject_id}/fingerprints/rollback"): "fingerprint.rollback",
    ("POST", "/api/subjects/{subject_id}/fingerprints/import"): "fingerprint.import",
    ("POST", "/api/sessions"): "session.create",
    ("POST", "/api/sessions/{session_id}/start"): "session.start",
    ("POST", "/api/sessions/{session_id}/stop"): "session.stop",
    ("PATCH", "/api/sessions/{session_id}/settings"): "settings.change",
    ("POST", "/api/sessions/{session_id}/settings/undo"): "settings.undo",
    ("POST", "/api/sessions/{session_id}/annotations"): "session.annotate",
    ("POST", "/api/sessions/{session_id}/recording"): "recording.start",
    ("POST", "/api/sessions/{session_id}/imu-calibration"): "imu_calibration.start",
    ("POST", "/api/sessions/{session_id}/gp-learning"): "gp_learning.control",
    ("POST", "/api/sessions/{session_id}/device-tokens"): "device_token.issue",
    ("DELETE", "/api/sessions/{session_id}/device-tokens/{token_id}"): "device_token.revoke",
    ("POST", "/api/sessions/{session_id}/exports"): "export.csv",
    ("POST", "/api/trials/{trial_id}/exports"): "export.pdf",
    ("POST", "/api/trials/{trial_id}/annotations"): "review_note.add",
    ("DELETE", "/api/trials/{trial_id}/annotations/{annotation_id}"): "review_note.delete",
    ("POST", "/api/uploads"): "upload.create",
    ("POST", "/api/uploads/{upload_id}/finish"): "upload.finish",
    ("DELETE", "/api/uploads/{upload_id}"): "upload.cancel",
    ("DELETE", "/api/mappings/{rig}"): "mapping.delete",
    ("POST", "/api/viewer/focus"): "leg_view.focus",
}
#: (method, route) -> why it writes no entry.
EXEMPT: dict[tuple[str, str], str] = {
    ("POST", "/api/uploads/{upload_id}/preview"): "reads an open upload and stores nothing; the import it previews "
    "is audited (upload.finish, with the mapping it used)",
    ("POST", "/api/sessions/{session_id}/settings/check"): "computes what a settings change would do to the torque "
    "and changes nothing; the change itself is audited (settings.change)",
    ("POST", "/api/trials/{trial_id}/rerun"): "computes a re-run of a stored trial and stores nothing",
    ("POST", "/api/trials/{trial_id}/compare"): "computes re-runs of a stored trial and stores nothing",
    ("PUT", "/api/uploads/{upload_id}"): "one chunk of the bytes of an upload whose creation and import are audited "
    "(upload.create, upload.finish); a cancelled one is too (upload.cancel)",
    ("POST", "/api/viewer/show"): "poses the shared view at a trial's time, many times a second while a reviewer "
    "drags the cursor, and stores nothing; the focus it drops is audited (leg_view.focus)",
}


@pytest.fixture
def client(tmp_path: Path) -> Iterator[TestClient]:
    settings = Settings(
        data_dir=tmp_path / "data", demo=False, leg_view=False, allowed_hosts=["testserver"], disk_warn_mb=1,
        disk_stop_mb=1, upload_min_free_mb=1, auth=True,
    )  # fmt: skip
    with TestClient(create_app(settings)) as c:
        c.app.state.ctx.accounts.add_user(  # type: ignore[attr-defined]
            schema.UserCreate(name="root", role="admin", password=PASSWORD), by="test"
        )
        yield c


def test_every_state_changing_route_is_audited_or_exempt_with_a_reason(client: TestClient) -> None:
    changing = {
        (method, route.path)
        for route in app_routes(client.app.routes)  # type: ignore[attr-defined]
        if isinstance(route, APIRoute)
        for method in route.methods
        if method not in SAFE_METHODS
    }
    assert not set(AUDITED) & set(EXEMPT)
    assert sorted(changing - set(AUDITED) - set(EXEMPT)) == [], "classify the new route: AUDITED or EXEMPT"
    assert sorted((set(AUDITED) | set(EXEMPT)) - changing) == []


class _Driver:
    """Sends requests as the logged-in admin and checks each audited route's entry."""

    def __init__(self, client: TestClient) -> None:
        self.client = client
        self.clock = ShiftedClock()  # the sessions' clock: a rate limit's wait is moved through, not slept
        client.app.state.ctx.manager.clock = self.clock  # type: ignore[attr-defined]
        self.driven: set[tuple[str, str]] = set()

    def login(self) -> None:
        self.client.headers.pop(CSRF_HEADER, None)
        self.call("POST", "/api/auth/login", {}, json={"name": "root", "password": PASSWORD})

    def call(self, method: str, route: str, ids: dict[str, Any], *, status: int | None = None, **kw: Any) -> Any:
        audit = self.client.app.state.ctx.audit  # type: ignore[attr-defined]
        before = audit.count()
        url = re.sub(r"\{(\w+)\}", lambda m: str(ids[m[1]]), route)
        r = self.client.request(method, url, **kw)
        for _ in range(5):  # a settings change too soon after the last: the server says when it may be made
            wait = re.search(r"try again in ([0-9.]+) s", r.text) if r.status_code == 409 else None
            if wait is None:
                break
            self.clock.advance(float(wait[1]) + 0.05)
            r = self.client.request(method, url, **kw)
        assert r.status_code == status if status else 200 <= r.status_code < 300, (method, url, r.status_code, r.text)
        if route == "/api/auth/login":
            self.client.headers[CSRF_HEADER] = r.json()["csrf_token"]
        action = AUDITED.get((method, route))
        if action is not None:
            new = audit.list(schema.AuditQuery(limit=max(1, audit.count() - before)))
            actions = {(e.action, e.user, e.outcome) for e in new}
            assert (action, "root", "done" if action == "login" else "requested") in actions or (
                action == "login" and ("login", "root", "requested") in actions
            ), (method, route, actions)
            self.driven.add((method, route))
        return r.json() if r.content else None


def test_each_audited_route_writes_its_entry_when_it_succeeds(client: TestClient) -> None:
    d = _Driver(client)
    d.login()
    d.call("POST", "/api/users", {}, json={"name": "ana", "role": "clinician", "password": PASSWORD})
    d.call("PATCH", "/api/users/{name}", {"name": "ana"}, json={"role": "experimenter"})
    subject = d.call("POST", "/api/subjects", {}, json={"code": "AU01", "leg_length_m": 0.9, "mass_kg": 70.0})["id"]
    ids: dict[str, Any] = {"subject_id": subject}
    d.call("PUT", "/api/subjects/{subject_id}/assistance-limits", ids, json={"torque_gain": 1.0})

    # a simulated session running the GP-EKF: settings, annotations, recording, learning, the leg view, exports
    body = {"subject_id": subject, "start": False, "settings": {"estimators": ["phase_ekf", GP_EKF]}}
    ids["session_id"] = d.call("POST", "/api/sessions", {}, json=body)["id"]
    d.call("POST", "/api/sessions/{session_id}/start", ids)
    d.call("PATCH", "/api/sessions/{session_id}/settings", ids, json={"torque_gain": 0.9})
    d.call("POST", "/api/sessions/{session_id}/settings/undo", ids, json={"confirm": True})  # it raises
    d.call("POST", "/api/sessions/{session_id}/annotations", ids, json={"text": "stumbled"})
    d.call("POST", "/api/sessions/{session_id}/recording", ids, json={"action": "start"})
    d.call("POST", "/api/sessions/{session_id}/gp-learning", ids, json={"action": "freeze"})
    d.call("POST", "/api/viewer/focus", {}, json={"session_id": ids["session_id"]})
    d.call("POST", "/api/sessions/{session_id}/stop", ids)
    d.call("POST", "/api/sessions/{session_id}/exports", ids, json={"kind": "csv"})

    # a device session: its token, and an IMU calibration
    source = {"kind": "device", "rate_hz": 200.0, "channels": IMU_CHANNELS}
    device = d.call("POST", "/api/sessions", {}, json={"subject_id": subject, "source": source})["id"]
    token = d.call("POST", "/api/sessions/{session_id}/device-tokens", {"session_id": device})["id"]
    d.call("DELETE", "/api/sessions/{session_id}/device-tokens/{token_id}", {"session_id": device, "token_id": token})
    d.call("POST", "/api/sessions/{session_id}/imu-calibration", {"session_id": device}, json={"duration_s": 2})

    # a recorded walk: a fingerprint calibrated, promoted, rolled back, exported and imported; review notes
    trial, _ = recorded(client, subject, walk_frames())
    made = d.call("POST", "/api/subjects/{subject_id}/fingerprints", ids, json={"trial_id": trial})
    ids["personalization_id"] = made["id"]
    d.call("POST", "/api/subjects/{subject_id}/fingerprints/{personalization_id}/promote", ids, json={})
    d.call("POST", "/api/subjects/{subject_id}/fingerprints/rollback", ids, json={})
    exported = d.call("GET", "/api/subjects/{subject_id}/fingerprints/{personalization_id}/export", ids)
    d.call("POST", "/api/subjects/{subject_id}/fingerprints/import", ids, json=exported)
    d.call("PUT", "/api/subjects/{subject_id}/intent-model", ids, json={"variant": "isci"})
    d.call("DELETE", "/api/subjects/{subject_id}/intent-model", ids)
    ids["trial_id"] = trial
    d.call("POST", "/api/trials/{trial_id}/exports", ids, json={"kind": "pdf"})
    note = d.call("POST", "/api/trials/{trial_id}/annotations", ids, json={"t": 2.0, "text": "heel strike late"})
    ids["annotation_id"] = note["id"]
    d.call("DELETE", "/api/trials/{trial_id}/annotations/{annotation_id}", ids)

    # uploads: one cancelled, one imported
    data = replay_csv()
    up = d.call("POST", "/api/uploads", {}, json={"filename": "a.CSV", "size": len(data), "subject_id": subject})
    d.call("DELETE", "/api/uploads/{upload_id}", {"upload_id": up["id"]})
    up = d.call("POST", "/api/uploads", {}, json={"filename": "B.CSV", "size": len(data), "subject_id": subject})
    for off in range(0, len(data), up["chunk_size"]):
        d.call("PUT", "/api/uploads/{upload_id}", {"upload_id": up["id"]}, params={"offset": off},
               content=data[off : off + up["chunk_size"]])  # fmt: skip
    trial = d.call("POST", "/api/uploads/{upload_id}/finish", {"upload_id": up["id"]})
    assert trial["samples"] > 0  # a name in capitals is imported as any other (issue #21: "x.CSV" was refused)
    client.app.state.ctx.mappings.save("c3d-0123456789abcdef", "c3d", "{}", "root")  # type: ignore[attr-defined]
    d.call("DELETE", "/api/mappings/{rig}", {"rig": "c3d-0123456789abcdef"})

    d.call("POST", "/api/auth/logout", {})
    d.login()
    d.call("POST", "/api/auth/password", {}, json={"current": PASSWORD, "new": "another good password"})

    assert sorted(set(AUDITED) - d.driven) == []


def test_the_leg_views_focus_is_audited_only_when_it_changes(client: TestClient) -> None:
    d = _Driver(client)
    d.login()
    audit = client.app.state.ctx.audit  # type: ignore[attr-defined]
    d.call("POST", "/api/viewer/focus", {}, json={"session_id": 5})
    n = audit.count()
    assert client.post("/api/viewer/focus", json={"session_id": 5}).status_code == 200
    assert audit.count() == n  # the same session again: nothing changed
    entry = audit.list(schema.AuditQuery(action="leg_view.focus", limit=1))[0]
    assert (entry.before, entry.after, entry.user) == (None, "5", "root")
