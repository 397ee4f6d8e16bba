"""Every route's rule, for every role: the OpenAPI document and the app's websockets are enumerated, each
route must be in :data:`EXPECTED` (a new route without a rule fails here), must declare that rule, and
answers each role as the rule says: 401 to nobody, 403 to a role without the permission, anything else
to a role with it; what each role gets is :data:`EXPECTED` read through ``gaitscope.server.auth.PERMISSIONS``, the one
table the guard itself reads. The real app with accounts on, a real SQLite file, real logins with argon2 hashes.

The gaps issue #21 found are pinned in :data:`EXPECTED` (``compare`` re-runs a trial: ``run``, as ``rerun``;
posing the shared leg view and starting exports: ``run``; the API's description: ``read``) and, for the one
that depends on the body (an experimenter choosing the primary estimator), in :data:`BODY_CASES`."""

from __future__ import annotations

import itertools
import re
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.dependencies.models import Dependant
from fastapi.routing import APIRoute, APIWebSocketRoute
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from gaitscope.server.app import create_app
from gaitscope.server.auth import CSRF_HEADER, PERMISSIONS, _device, _Guard, _public
from gaitscope.sessions import schema
from tests.server.apps import PASSWORD, app_routes, auth_settings, login

#: (method, path) -> the permission it needs; "public": anyone; "device": its session's device token.
EXPECTED: dict[tuple[str, str], str] = {
    ("GET", "/api/health"): "public",
    ("GET", "/openapi.json"): "read",
    ("GET", "/docs"): "read",
    ("GET", "/redoc"): "read",
    ("GET", "/api/schema"): "read",
    ("GET", "/api/cluster/route"): "public",  # the proxy's question: which node runs a session (404 off a cluster)
    ("GET", "/api/cluster/nodes"): "read",
    ("POST", "/api/auth/login"): "public",
    ("POST", "/api/auth/logout"): "login",
    ("GET", "/api/auth/me"): "login",
    ("POST", "/api/auth/password"): "login",
    ("GET", "/api/users"): "admin",
    ("POST", "/api/users"): "admin",
    ("PATCH", "/api/users/{name}"): "admin",
    ("GET", "/api/audit"): "admin",
    ("GET", "/api/audit.csv"): "admin",
    ("GET", "/api/audit/verify"): "admin",
    ("POST", "/api/sessions/{session_id}/device-tokens"): "run",
    ("GET", "/api/sessions/{session_id}/device-tokens"): "read",
    ("DELETE", "/api/sessions/{session_id}/device-tokens/{token_id}"): "run",
    ("GET", "/api/subjects"): "read",
    ("POST", "/api/subjects"): "run",
    ("GET", "/api/subjects/{subject_id}"): "read",
    ("GET", "/api/subjects/{subject_id}/assistance-limits"): "read",
    ("PUT", "/api/subjects/{subject_id}/assistance-limits"): "set_limits",
    ("GET", "/api/subjects/{subject_id}/fingerprints"): "read",
    ("GET", "/api/subjects/{subject_id}/intent-model"): "read",
    ("PUT", "/api/subjects/{subject_id}/intent-model"): "promote",
    ("DELETE", "/api/subjects/{subject_id}/intent-model"): "promote",
    ("POST", "/api/subjects/{subject_id}/fingerprints"): "run",
    ("POST", "/api/subjects/{subject_id}/fingerprints/{personalization_id}/promote"): "promote",
    ("POST", "/api/subjects/{subject_id}/fingerprints/rollback"): "promote",
    ("GET", "/api/subjects/{subject_id}/fingerprints/{personalization_id}/export"): "read",
    ("POST", "/api/subjects/{subject_id}/fingerprints/import"): "upload",
    ("GET", "/api/subjects/{subject_id}/imu-calibrations"): "read",
    ("GET", "/api/sessions"): "read",
    ("POST", "/api/sessions"): "run",
    ("GET", "/api/sessions/{session_id}"): "read",
    ("POST", "/api/sessions/{session_id}/start"): "run",
    ("POST", "/api/sessions/{session_id}/stop"): "run",
    ("PATCH", "/api/sessions/{session_id}/settings"): "assist_within_limits",
    ("POST", "/api/sessions/{session_id}/settings/undo"): "assist_within_limits",
    ("POST", "/api/sessions/{session_id}/settings/check"): "read",
    ("GET", "/api/sessions/{session_id}/events"): "read",
    ("POST", "/api/sessions/{session_id}/annotations"): "annotate",
    ("POST", "/api/sessions/{session_id}/recording"): "run",
    ("POST", "/api/sessions/{session_id}/imu-calibration"): "run",
    ("GET", "/api/sessions/{session_id}/imu-calibration"): "read",
    ("GET", "/api/sessions/{session_id}/gp-learning"): "read",
    ("POST", "/api/sessions/{session_id}/gp-learning"): "run",
    ("GET", "/api/sessions/{session_id}/summary"): "read",
    ("GET", "/api/sessions/{session_id}/summary/progress"): "read",
    ("POST", "/api/sessions/{session_id}/exports"): "run",
    ("POST", "/api/trials/{trial_id}/exports"): "run",
    ("GET", "/api/exports/{job_id}"): "read",
    ("GET", "/api/exports/{job_id}/file"): "read",
    ("GET", "/api/models"): "read",
    ("GET", "/api/estimators"): "read",
    ("GET", "/api/trials"): "read",
    ("GET", "/api/trials/{trial_id}"): "read",
    ("GET", "/api/trials/{trial_id}/events"): "read",
    ("GET", "/api/trials/{trial_id}/series"): "read",
    ("GET", "/api/trials/{trial_id}/intent"): "read",
    ("GET", "/api/trials/{trial_id}/download"): "read",
    ("GET", "/api/trials/{trial_id}/settings"): "read",
    ("GET", "/api/trials/{trial_id}/estimators"): "read",
    ("POST", "/api/trials/{trial_id}/rerun"): "run",
    ("POST", "/api/trials/{trial_id}/compare"): "run",
    ("GET", "/api/trials/{trial_id}/annotations"): "read",
    ("POST", "/api/trials/{trial_id}/annotations"): "annotate",
    ("DELETE", "/api/trials/{trial_id}/annotations/{annotation_id}"): "annotate",
    ("POST", "/api/uploads"): "upload",
    ("PUT", "/api/uploads/{upload_id}"): "upload",
    ("POST", "/api/uploads/{upload_id}/finish"): "upload",
    ("POST", "/api/uploads/{upload_id}/preview"): "upload",
    ("GET", "/api/mappings"): "read",
    ("DELETE", "/api/mappings/{rig}"): "upload",
    ("DELETE", "/api/uploads/{upload_id}"): "upload",
    ("GET", "/api/viewer"): "read",
    ("POST", "/api/viewer/focus"): "run",
    ("POST", "/api/viewer/show"): "run",
    ("WEBSOCKET", "/ws/sessions/{session_id}"): "read",
    ("WEBSOCKET", "/ws/devices/{session_id}"): "device",
}


@pytest.fixture(scope="module")
def app_with_users(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """The app with accounts on and one user of each role (``<role>1``)."""
    with TestClient(create_app(auth_settings(tmp_path_factory.mktemp("roles")))) as c:
        for role in schema.ROLES:
            c.app.state.ctx.accounts.add_user(  # type: ignore[attr-defined]
                schema.UserCreate(name=f"{role}1", role=role, password=PASSWORD), by="test"
            )
        yield c


#: The routes left out of the OpenAPI document: the document itself and its two viewers.
HIDDEN = {("GET", "/openapi.json"), ("GET", "/docs"), ("GET", "/redoc")}


def _routes(client: TestClient) -> set[tuple[str, str]]:
    """Every REST route of the OpenAPI document, and every websocket route of the app."""
    document = client.app.openapi()  # type: ignore[attr-defined]
    found = {(m.upper(), path) for path, item in document["paths"].items() for m in item}
    walked = list(app_routes(client.app.routes))  # type: ignore[attr-defined]
    found |= {("WEBSOCKET", r.path) for r in walked if isinstance(r, APIWebSocketRoute)}
    rest = {(m, r.path) for r in walked if isinstance(r, APIRoute) for m in r.methods}
    assert rest - found == HIDDEN  # none hidden but these
    return found | HIDDEN


def _rules(dependant: Dependant) -> list[str]:
    """The rules a route's dependencies declare (its own and its dependencies')."""
    out = []
    for d in dependant.dependencies:
        call = d.call
        if isinstance(call, _Guard):
            out.append("login" if call.permission is None else call.permission)
        elif call is _public:
            out.append("public")
        elif call is _device:
            out.append("device")
        out.extend(_rules(d))
    return out


def test_every_route_has_a_rule_and_declares_it(app_with_users: TestClient) -> None:
    routes = _routes(app_with_users)
    assert sorted(set(routes) - set(EXPECTED)) == [], "routes without an expected rule: add them to EXPECTED"
    assert sorted(set(EXPECTED) - set(routes)) == [], "rules for routes that do not exist"
    for route in app_routes(app_with_users.app.routes):  # type: ignore[attr-defined]
        if isinstance(route, APIRoute):
            for method in route.methods:
                assert _rules(route.dependant) == [EXPECTED[(method, route.path)]], (method, route.path)
        elif isinstance(route, APIWebSocketRoute):
            assert _rules(route.dependant) == [EXPECTED[("WEBSOCKET", route.path)]], route.path


def _url(path: str) -> str:
    return re.sub(r"\{(\w+)\}", lambda m: "nobody" if m[1] in ("name", "upload_id") else "999", path)


def _may(role: schema.Role, rule: str) -> bool:
    return rule in ("public", "login") or rule in PERMISSIONS[role]


@pytest.mark.parametrize("role", [None, *schema.ROLES])
def test_every_route_answers_each_role_as_its_rule_says(app_with_users: TestClient, role: schema.Role | None) -> None:
    client = app_with_users
    headers = {} if role is None else login(client, f"{role}1")
    checked = 0
    for (method, path), rule in EXPECTED.items():
        if method == "WEBSOCKET" or (method, path) in {("POST", "/api/auth/login"), ("POST", "/api/auth/logout")}:
            continue  # websockets below; logging in and out is test_auth's
        if (method, path) == ("POST", "/api/auth/password"):
            body: Any = {"current": "wrong password", "new": "another good password"}
        else:
            body = {} if method in ("POST", "PUT", "PATCH") else None
        r = client.request(method, _url(path), json=body, headers=headers)
        if rule == "public":
            assert r.status_code not in (401, 403), (method, path, r.status_code, r.text)
        elif role is None:
            assert r.status_code == 401, (method, path, r.status_code, r.text)
        elif not _may(role, rule):
            assert r.status_code == 403, (role, method, path, r.status_code, r.text)
            assert "may not" in r.json()["detail"]
        else:
            assert r.status_code not in (401, 403) or (method, path) == ("POST", "/api/auth/password"), (
                role, method, path, r.status_code, r.text,
            )  # fmt: skip
        checked += 1
    assert checked == len(EXPECTED) - 4


@pytest.mark.parametrize("role", [None, *schema.ROLES])
def test_the_session_stream_needs_a_login(app_with_users: TestClient, role: schema.Role | None) -> None:
    headers = {} if role is None else login(app_with_users, f"{role}1")
    with pytest.raises(WebSocketDisconnect) as exc:
        with app_with_users.websocket_connect("/ws/sessions/999", headers=headers) as ws:
            ws.receive_text()
    # nobody: refused (1008) before anything; a role: let in, then told there is no session 999
    assert (exc.value.code == 1008) == (role is None), (role, exc.value.code, exc.value.reason)


def test_state_changes_need_the_logins_csrf_token(app_with_users: TestClient) -> None:
    client = app_with_users
    headers = login(client, "clinician1")
    body = {"code": "CSRF1", "leg_length_m": 0.9, "mass_kg": 70}
    for sent in ({"cookie": headers["cookie"]}, {"cookie": headers["cookie"], CSRF_HEADER: "forged"}):
        r = client.post("/api/subjects", json=body, headers=sent)
        assert r.status_code == 403 and CSRF_HEADER in r.json()["detail"], r.text
    assert client.get("/api/subjects", headers={"cookie": headers["cookie"]}).status_code == 200  # reads need none
    assert client.post("/api/subjects", json=body, headers=headers).status_code == 201


#: Outcomes that depend on the body: (role, method, path, body, status). An experimenter may never choose or
#: switch the estimator driving the torque (issue #21: a session whose primary is ``tbe`` was created).
BODY_CASES: list[tuple[schema.Role, str, str, dict[str, Any], int]] = [
    ("experimenter", "POST", "/api/sessions", {"settings": {"primary": "tbe"}}, 403),
    ("experimenter", "POST", "/api/sessions", {"settings": {"primary": "tbe"}, "source": {"kind": "device"}}, 403),
    ("experimenter", "POST", "/api/sessions", {"settings": {"primary": "phase_ekf"}}, 201),
    ("experimenter", "POST", "/api/sessions", {}, 201),
    ("clinician", "POST", "/api/sessions", {"settings": {"primary": "tbe"}}, 201),
    ("admin", "POST", "/api/sessions", {"settings": {"primary": "tbe"}}, 201),
]


_SUBJECTS = itertools.count(1)


@pytest.mark.parametrize(("role", "method", "path", "body", "status"), BODY_CASES)
def test_what_a_role_may_depends_on_the_body_as_the_table_says(
    app_with_users: TestClient, role: schema.Role, method: str, path: str, body: dict[str, Any], status: int
) -> None:
    client = app_with_users
    admin = login(client, "admin1")
    code = f"BODY{next(_SUBJECTS)}"
    r = client.post("/api/subjects", json={"code": code, "leg_length_m": 0.9, "mass_kg": 70}, headers=admin)
    assert r.status_code == 201, r.text
    headers = login(client, f"{role}1")
    r = client.request(method, path, json={"subject_id": r.json()["id"], "start": False, **body}, headers=headers)
    assert r.status_code == status, (role, body, r.status_code, r.text)
    if status == 403:
        assert "may not switch the estimator driving the torque" in r.json()["detail"]


def test_the_api_description_needs_a_login(app_with_users: TestClient) -> None:
    client = app_with_users
    for path in ("/openapi.json", "/docs", "/redoc"):
        assert client.get(path).status_code == 401, path
    headers = login(client, "viewer1")
    assert "/api/sessions" in client.get("/openapi.json", headers=headers).json()["paths"]
    assert "swagger" in client.get("/docs", headers=headers).text.lower()
