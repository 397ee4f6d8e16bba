"""The audit trail over HTTP and on the command line: ``/api/audit`` (list, filters, CSV, verify), refused
requests written by the middleware, and ``gaitscope audit verify|export`` on a good and a tampered database.

The real app on a real database (SQLite in the test's folder, or PostgreSQL when ``GAITSCOPE_TEST_POSTGRES`` is
set), with accounts off (everyone is ``local``, an admin) except where a test turns them on.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import create_engine
from sqlalchemy.pool import NullPool
from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import JSONResponse, Response, StreamingResponse
from starlette.routing import Route, WebSocketRoute
from starlette.websockets import WebSocket

from gaitscope.server.app import create_app
from gaitscope.server.audit_middleware import BODY_MAX, AuditMiddleware
from gaitscope.server.auth import COOKIE, CSRF_HEADER
from gaitscope.server.cli import main
from gaitscope.server.settings import Settings
from gaitscope.sessions import schema
from gaitscope.sessions.audit import AuditLog
from gaitscope.sessions.audit.export import COLUMNS
from gaitscope.sessions.audit.tables import drop_triggers
from gaitscope.sessions.store import Store

SUBJECT = {"code": "AB01", "leg_length_m": 0.9, "mass_kg": 70.0}
PASSWORD = "correct horse battery"


def _audit(client: TestClient) -> AuditLog:
    return client.app.state.ctx.audit  # type: ignore[attr-defined, no-any-return]


def _entries(client: TestClient, **filters: Any) -> list[dict[str, Any]]:
    r = client.get("/api/audit", params=filters)
    assert r.status_code == 200, r.text
    return r.json()  # type: ignore[no-any-return]


def _tamper(database_url: str, statement: str) -> None:
    engine = create_engine(database_url, poolclass=NullPool)
    try:
        with engine.begin() as c:
            drop_triggers(c)
            c.exec_driver_sql(statement)
    finally:
        engine.dispose()


# --- reading the trail ------------------------------------------------------------------------------------


def test_list_filters_and_pages(client: TestClient) -> None:
    audit = _audit(client)
    for i in range(6):
        audit.record(user=f"u{i % 2}", role="clinician", action=f"session.{('start', 'stop')[i % 2]}",
                     target=f"session {i}", after={"i": i})  # fmt: skip
    audit.record(user="u9", role="none", action="login.failed", target="10.0.0.9", outcome="refused")
    everything = _entries(client)
    assert [e["seq"] for e in everything] == [7, 6, 5, 4, 3, 2, 1]
    first = everything[-1]
    assert first["prev_hash"] == "0" * 64 and first["after"] == '{"i":0}' and first["outcome"] == "requested"
    assert schema.AuditEntry.model_validate(first).hash == audit.list()[-1].hash
    assert [e["seq"] for e in _entries(client, user="u1")] == [6, 4, 2]
    assert [e["seq"] for e in _entries(client, action="session.st", limit=2, offset=1)] == [5, 4]
    assert [e["seq"] for e in _entries(client, outcome="refused")] == [7]
    assert [e["seq"] for e in _entries(client, target="session 3")] == [4]
    assert _entries(client, since="2999-01-01") == []


@pytest.mark.parametrize(
    ("params", "where", "message"),
    [
        ({"limit": "0"}, ["query", "limit"], "Input should be greater than or equal to 1"),
        ({"since": "last week"}, ["query", "since"], "not an ISO-8601 date or time: 'last week'"),
        ({"outcome": "ok"}, ["query", "outcome"], "Input should be 'requested', 'done', 'failed' or 'refused'"),
        ({"colour": "red"}, ["query", "colour"], "Extra inputs are not permitted"),
    ],
)
def test_bad_filters_answer_422_naming_the_parameter(
    client: TestClient, params: dict[str, str], where: list[str], message: str
) -> None:
    r = client.get("/api/audit", params=params)
    assert r.status_code == 422
    (error,) = r.json()["detail"]
    assert error["loc"] == where and message in error["msg"]
    assert client.get("/api/audit.csv", params=params).status_code == 422
    assert _audit(client).count() == 0  # a refused read is not a refused change: not audited


def test_verify_reports_an_intact_then_a_tampered_chain(client: TestClient) -> None:
    audit = _audit(client)
    for i in range(20):
        audit.record(user="ana", role="admin", action="settings.change", target="session 1", after={"gain": i})
    r = client.get("/api/audit/verify")
    assert r.status_code == 200
    assert r.json() == {"ok": True, "entries": 20, "first_bad_seq": None, "problem": None, "keyed_from": 1,
                        "checkpoint_seq": None,
                        "last_hash": audit.list(schema.AuditQuery(limit=1))[0].hash}  # fmt: skip
    _tamper(client.app.state.ctx.settings.database_url, "UPDATE audit SET after = '{\"gain\":0.5}' WHERE seq = 17")  # type: ignore[attr-defined]
    assert client.get("/api/audit/verify").json() == {
        "ok": False, "entries": 16, "first_bad_seq": 17, "last_hash": None, "keyed_from": 1, "checkpoint_seq": None,
        "problem": "hash mismatch at seq 17 (the entry was changed)",
    }  # fmt: skip


# --- CSV ------------------------------------------------------------------------------------------------


def test_csv_is_rfc4180_formula_safe_filtered_and_audited(client: TestClient) -> None:
    audit = _audit(client)
    audit.record(user="ana", role="admin", action="upload", target='=HYPERLINK("http://x","y")', detail="+1 line\nx")
    audit.record(user="ana", role="admin", action="upload", target="@SUM(A1)", before=-1.5, after="-2")
    audit.record(user="bob", role="viewer", action="download", target="trial 3", detail='say "hi", ok')
    r = client.get("/api/audit.csv", params={"user": "ana", "limit": 1})
    assert r.status_code == 200
    assert r.headers["content-type"] == "text/csv; charset=utf-8"
    assert r.headers["content-disposition"].startswith('attachment; filename="gaitscope-audit-')
    assert r.text.startswith(",".join(COLUMNS) + "\r\n")  # header row, CRLF line ends
    rows = list(csv.DictReader(io.StringIO(r.text, newline="")))
    assert [row["seq"] for row in rows] == ["1", "2"]  # all of ana's, oldest first: limit is for pages only
    assert rows[0]["target"] == '\'=HYPERLINK("http://x","y")' and rows[0]["detail"] == "'+1 line\nx"
    assert rows[1]["target"] == "'@SUM(A1)" and rows[1]["before"] == "'-1.5" and rows[1]["after"] == '"-2"'
    assert rows[0]["hash"] == audit.list(schema.AuditQuery(user="ana"))[-1].hash
    export = audit.list(schema.AuditQuery(action="audit.export"))
    assert [(e.user, e.role, e.target, e.after) for e in export] == [("local", "admin", "audit", '{"user":"ana"}')]
    everything = list(csv.reader(io.StringIO(client.get("/api/audit.csv").text, newline="")))
    assert len(everything) == 1 + 5  # the three entries and the two exports
    assert everything[3][COLUMNS.index("detail")] == 'say "hi", ok'


def test_a_large_csv_streams_in_pieces(client: TestClient) -> None:
    audit = _audit(client)
    for i in range(1200):
        audit.record(user="ana", role="admin", action="x", target=str(i))
    with client.stream("GET", "/api/audit.csv") as r:
        pieces = list(r.iter_text())
    rows = list(csv.reader(io.StringIO("".join(pieces), newline="")))
    assert len(rows) == 1 + 1201 and rows[-1][COLUMNS.index("action")] == "audit.export"


# --- refused requests (the middleware) --------------------------------------------------------------------


def test_a_422_on_a_state_change_is_recorded(client: TestClient) -> None:
    r = client.post("/api/subjects", json={**SUBJECT, "leg_length_m": 7})
    assert r.status_code == 422
    (e,) = _audit(client).list(schema.AuditQuery(outcome="refused"))
    assert (e.user, e.role, e.action, e.target) == ("local", "admin", "refused POST /api/subjects", "/api/subjects")
    assert e.detail == "422: body.leg_length_m: Input should be less than or equal to 1.3"


def test_a_409_is_recorded_with_the_route_template(client: TestClient) -> None:
    assert client.post("/api/subjects", json=SUBJECT).status_code == 201
    r = client.post("/api/subjects", json=SUBJECT)
    assert r.status_code == 409
    r = client.put("/api/subjects/1/assistance-limits", json={"torque_gain": "lots"})
    assert r.status_code == 422
    refused = _audit(client).list(schema.AuditQuery(outcome="refused"))
    assert [(e.action, e.target) for e in refused] == [
        ("refused PUT /api/subjects/{subject_id}/assistance-limits", "/api/subjects/1/assistance-limits"),
        ("refused POST /api/subjects", "/api/subjects"),
    ]
    assert refused[1].detail == f"409: {client.post('/api/subjects', json=SUBJECT).json()['detail']}"
    assert _audit(client).verify().ok


def test_a_cross_origin_refusal_is_recorded_and_reads_and_other_errors_are_not(client: TestClient) -> None:
    r = client.post("/api/subjects", json=SUBJECT, headers={"Origin": "http://evil.example"})
    assert r.status_code == 403 and r.json()["detail"] == "cross-origin request from http://evil.example refused"
    assert client.get("/api/subjects/99").status_code == 404
    assert client.get("/api/audit", params={"limit": 0}).status_code == 422  # a read
    assert client.post("/api/sessions/99/start").status_code == 404  # not a refusal
    (e,) = _audit(client).list()
    assert (e.action, e.outcome) == ("refused POST /api/subjects", "refused")
    assert e.detail == "403: cross-origin request from http://evil.example refused"


def test_with_accounts_on_the_pages_are_the_admins_and_refusals_name_the_caller(tmp_path: Path) -> None:
    settings = Settings(
        data_dir=tmp_path / "data", demo=False, leg_view=False, allowed_hosts=["testserver"], disk_warn_mb=1,
        disk_stop_mb=1, upload_min_free_mb=1, auth=True,
    )  # fmt: skip
    with TestClient(create_app(settings)) as client:
        for name, role in (("root", "admin"), ("vera", "viewer")):
            client.app.state.ctx.accounts.add_user(  # type: ignore[attr-defined]
                schema.UserCreate(name=name, role=role, password=PASSWORD), by="test"
            )

        def login(name: str) -> dict[str, str]:
            client.cookies.clear()
            r = client.post("/api/auth/login", json={"name": name, "password": PASSWORD})
            assert r.status_code == 200, r.text
            token = client.cookies.get(COOKIE)
            client.cookies.clear()
            return {"cookie": f"{COOKIE}={token}", CSRF_HEADER: r.json()["csrf_token"]}

        admin, viewer = login("root"), login("vera")
        for path in ("/api/audit", "/api/audit.csv", "/api/audit/verify"):
            assert client.get(path).status_code == 401
            assert client.get(path, headers=viewer).status_code == 403
            assert client.get(path, headers=admin).status_code == 200
        assert client.post("/api/subjects", json=SUBJECT, headers=viewer).status_code == 403
        assert client.post("/api/subjects", json=SUBJECT).status_code == 401
        no_csrf = {"cookie": admin["cookie"]}
        assert client.post("/api/subjects", json=SUBJECT, headers=no_csrf).status_code == 403
        refused = _entries_as(client, admin, outcome="refused")
        assert [(e["user"], e["role"], e["action"], e["detail"][:4]) for e in refused] == [
            ("root", "admin", "refused POST /api/subjects", "403:"),
            ("anonymous", "none", "refused POST /api/subjects", "401:"),
            ("vera", "viewer", "refused POST /api/subjects", "403:"),
        ]
        assert "may not run sessions and trials" in refused[2]["detail"]
        exports = _entries_as(client, admin, action="audit.export")
        assert [(e["user"], e["role"]) for e in exports] == [("root", "admin")]
        r = client.get("/api/audit/verify", headers=admin)
        assert r.json()["ok"] is True


def _entries_as(client: TestClient, headers: dict[str, str], **filters: Any) -> list[dict[str, Any]]:
    r = client.get("/api/audit", params=filters, headers=headers)
    assert r.status_code == 200, r.text
    return r.json()  # type: ignore[no-any-return]


# --- the middleware on its own: streams and websockets pass through untouched ------------------------------


class _Ctx:
    def __init__(self, store: Store) -> None:
        self.audit = AuditLog(store, b"k" * 32)
        self.settings = Settings(auth=False)


@pytest.fixture
def bare(database_url: str) -> Iterator[tuple[TestClient, AuditLog]]:
    """A tiny Starlette app behind the middleware: a long refused stream, a long good one, a websocket."""

    def chunks(n: int) -> Iterator[bytes]:
        for _ in range(n):
            yield b"x" * 1024

    async def refused_stream(_: Request) -> Response:
        return StreamingResponse(chunks(BODY_MAX // 1024 + 10), status_code=409, media_type="application/json")

    async def good_stream(_: Request) -> Response:
        return StreamingResponse(chunks(200), media_type="application/octet-stream")

    async def refused_json(_: Request) -> Response:
        return JSONResponse({"detail": "d" * 900}, status_code=422)

    async def echo(ws: WebSocket) -> None:
        await ws.accept()
        await ws.send_text(await ws.receive_text())
        await ws.close()

    store = Store(database_url)
    app = Starlette(routes=[
        Route("/refused", refused_stream, methods=["POST"]), Route("/good", good_stream, methods=["POST", "GET"]),
        Route("/json/{x}", refused_json, methods=["DELETE", "GET"]), WebSocketRoute("/ws", echo),
    ])  # fmt: skip
    app.add_middleware(AuditMiddleware)
    app.state.ctx = _Ctx(store)
    with TestClient(app) as c:
        yield c, app.state.ctx.audit
    store.close()


def test_streams_and_websockets_pass_through(bare: tuple[TestClient, AuditLog]) -> None:
    client, audit = bare
    r = client.post("/refused")
    assert r.status_code == 409 and r.content == b"x" * 1024 * (BODY_MAX // 1024 + 10)
    r = client.post("/good")
    assert r.status_code == 200 and len(r.content) == 200 * 1024
    r = client.get("/json/1")
    assert r.status_code == 422
    with client.websocket_connect("/ws") as ws:
        ws.send_text("hello")
        assert ws.receive_text() == "hello"
    r = client.delete("/json/7")
    assert r.status_code == 422 and len(r.json()["detail"]) == 900
    entries = audit.list()
    assert [(e.action, e.target, e.detail) for e in entries] == [
        ("refused DELETE /json/{x}", "/json/7", "422: " + "d" * 500),
        ("refused POST /refused", "/refused", "409"),  # a body too large to hold is not read
    ]


# --- the command line ------------------------------------------------------------------------------------


def test_cli_verify_and_export(client: TestClient, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    audit = _audit(client)
    for i in range(30):
        audit.record(user="ana", role="admin", action="settings.change", target="session 1", after={"gain": i})
    data = str(tmp_path / "data")
    assert main(["audit", "verify", "--data-dir", data]) == 0
    out = capsys.readouterr().out
    assert out.startswith("audit trail intact: 30 entries\nnewest hash: ")
    out_csv = tmp_path / "out" / "audit.csv"
    assert main(["audit", "--data-dir", data, "export", "--out", str(out_csv), "--since", "2000-01-01"]) == 0
    assert capsys.readouterr().out == f"wrote 31 entries to {out_csv}\n"  # the export's own entry included
    with out_csv.open(encoding="utf-8", newline="") as f:
        rows = list(csv.reader(f))
    assert rows[0] == list(COLUMNS) and len(rows) == 32 and rows[-1][COLUMNS.index("user")] == "cli"
    assert main(["audit", "verify", "--data-dir", data]) == 0
    assert "31 entries" in capsys.readouterr().out

    mark = tmp_path / "elsewhere" / "checkpoint.json"
    assert main(["audit", "checkpoint", "--data-dir", data, "--out", str(mark)]) == 0
    assert capsys.readouterr().out.startswith("wrote the checkpoint of seq 32 (hash ")  # its own entry included
    assert schema.AuditCheckpoint.model_validate_json(mark.read_text()).seq == 32
    assert main(["audit", "verify", "--data-dir", data, "--checkpoint", str(mark)]) == 0
    assert "no entry up to seq 32 (the checkpoint) was cut off or rewritten" in capsys.readouterr().out

    _tamper(client.app.state.ctx.settings.database_url, "DELETE FROM audit WHERE seq >= 31")  # type: ignore[attr-defined]
    assert main(["audit", "verify", "--data-dir", data]) == 0  # cut at its end, a chain is still a chain
    capsys.readouterr()
    assert main(["audit", "verify", "--data-dir", data, "--checkpoint", str(mark)]) == 1
    assert "entries 31 to 32 were cut off" in capsys.readouterr().out
    _tamper(client.app.state.ctx.settings.database_url, "DELETE FROM audit WHERE seq = 18")  # type: ignore[attr-defined]
    assert main(["audit", "verify", "--data-dir", data]) == 1
    assert (
        capsys.readouterr().out == "audit trail BROKEN after 17 good entries: seq 18 missing (an entry was deleted)\n"
    )


def test_cli_needs_the_servers_audit_key(
    client: TestClient, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    _audit(client).record(user="ana", role="admin", action="x", target="t")
    data = tmp_path / "data"
    (data / "audit.key").rename(tmp_path / "moved.key")
    assert main(["audit", "verify", "--data-dir", str(data)]) == 2
    assert "no audit key: set GAITSCOPE_AUDIT_KEY" in capsys.readouterr().err
    assert main(["audit", "checkpoint", "--data-dir", str(data), "--out", str(tmp_path / "c.json")]) == 2
    assert not (data / "audit.key").exists()  # only writers make a key, and only where the trail has none
    monkeypatch.setenv("GAITSCOPE_AUDIT_KEY", "another key, not the server's one!")
    assert main(["audit", "verify", "--data-dir", str(data)]) == 1
    assert "MAC mismatch at seq 1" in capsys.readouterr().out
    out = tmp_path / "c.json"
    assert main(["audit", "checkpoint", "--data-dir", str(data), "--out", str(out)]) == 2
    assert "was not written with this audit key" in capsys.readouterr().err and not out.exists()
    monkeypatch.setenv("GAITSCOPE_AUDIT_KEY", (tmp_path / "moved.key").read_text())
    assert main(["audit", "verify", "--data-dir", str(data)]) == 0


def test_cli_refuses_bad_input(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("GAITSCOPE_DATABASE_URL", raising=False)  # the SQLite file of --data-dir, even on PostgreSQL
    assert main(["audit", "verify", "--data-dir", str(tmp_path / "nowhere")]) == 2
    err = capsys.readouterr().err
    assert "no database there: give the server's --data-dir" in err and "nowhere" in err
    assert not (tmp_path / "nowhere").exists()
    out = str(tmp_path / "a.csv")
    assert main(["audit", "export", "--out", out, "--since", "soon", "--data-dir", str(tmp_path)]) == 2
    assert "--since: Value error, not an ISO-8601 date or time: 'soon'" in capsys.readouterr().err
