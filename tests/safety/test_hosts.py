"""DNS rebinding: a request naming a host outside the allowlist is refused, on both ports.

A page on ``evil.example`` whose name is re-resolved to 127.0.0.1 makes the browser connect to this
machine while it sends ``Host: evil.example:PORT`` and ``Origin: http://evil.example:PORT``. The tests
do exactly that against a real ``gaitscope serve`` (loopback socket, forged headers): the API, the
UI, both websockets and the viser leg view's port refuse it, and the allowed names still work.
"""

from __future__ import annotations

import contextlib
import http.client
import json
import os
import socket
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import pytest
import viser
from fastapi.testclient import TestClient
from pydantic import ValidationError
from websockets.exceptions import InvalidStatus
from websockets.sync.client import ClientConnection, connect
from websockets.typing import Origin, Subprotocol

import gaitscope.server.leg_view
from gaitscope.server.app import create_app
from gaitscope.server.bench.launch import LOOPBACK, free_port, start_server
from gaitscope.server.leg_view import LegView
from gaitscope.server.settings import Settings
from tests.device_tokens import issue_token

#: A real server over real sockets: seconds per test, and timing depends on the machine's load.
pytestmark = pytest.mark.slow

EVIL = "evil.example"
NOT_ALLOWED = f"host '{EVIL}' is not allowed (add it to GAITSCOPE_ALLOWED_HOSTS to serve it)"
#: The real server's allowlist: the loopback names (IPv6 bracketed, as people write it) and one more.
ALLOWED_ENV = "127.0.0.1,localhost,[::1],gait.lab"
ALLOWED = ("127.0.0.1", "localhost", "[::1]", "gait.lab")


@dataclass
class Live:
    port: int
    viser_port: int
    session_id: int


def _http(port: int, method: str, path: str, host: str, origin: str | None = None, body: Any = None) -> tuple[int, Any]:
    """One request over a loopback socket with the given Host (and Origin); status and decoded body."""
    conn = http.client.HTTPConnection(LOOPBACK, port, timeout=10)
    headers = {"Host": host} | ({"Origin": origin} if origin else {})
    if body is not None:
        headers["Content-Type"] = "application/json"
    try:
        conn.request(method, path, body=None if body is None else json.dumps(body), headers=headers)
        r = conn.getresponse()
        data = r.read()
        kind = r.getheader("Content-Type") or ""
        return r.status, json.loads(data) if kind.startswith("application/json") else data
    finally:
        conn.close()


def _ws(port: int, path: str, host: str, origin: str | None, **kw: Any) -> ClientConnection:
    """A websocket to ``ws://host/path`` over a loopback socket: the browser after rebinding."""
    sock = socket.create_connection((LOOPBACK, port), timeout=10)
    try:
        return connect(f"ws://{host}{path}", sock=sock, origin=None if origin is None else Origin(origin), **kw)
    except BaseException:
        sock.close()
        raise


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Live]:
    env = {**os.environ, "GAITSCOPE_ALLOWED_HOSTS": ALLOWED_ENV}
    srv = start_server(tmp_path_factory.mktemp("data"), "--no-demo", "--viser-port", str(free_port()), env=env)
    try:
        host = f"{LOOPBACK}:{srv.port}"
        body = {"code": "H1", "leg_length_m": 0.9, "mass_kg": 70}
        status, subject = _http(srv.port, "POST", "/api/subjects", host, body=body)
        assert status == 201, subject
        new = {"subject_id": subject["id"], "source": {"kind": "device"}}
        status, session = _http(srv.port, "POST", "/api/sessions", host, body=new)
        assert status == 201 and session["state"] == "running", session
        _, viewer = _http(srv.port, "GET", "/api/viewer", host)
        url = urlsplit(viewer["url"])
        assert url.hostname == LOOPBACK and url.port is not None  # the leg view binds the server's host
        yield Live(srv.port, url.port, session["id"])
    finally:
        srv.stop()


# --- the dashboard's port ------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("method", "path", "body"),
    [
        ("GET", "/api/sessions", None),
        ("GET", "/api/sessions/{sid}", None),
        ("GET", "/api/sessions/{sid}/events", None),
        ("GET", "/", None),  # the UI itself
        ("GET", "/docs", None),
        ("POST", "/api/sessions/{sid}/stop", None),
        ("PATCH", "/api/sessions/{sid}/settings", {"torque_gain": 1.5, "confirm": True}),
    ],
)
def test_rebound_host_is_refused_on_every_route(live: Live, method: str, path: str, body: Any) -> None:
    forged = f"{EVIL}:{live.port}"
    url = path.format(sid=live.session_id)
    assert _http(live.port, method, url, forged, f"http://{forged}", body) == (400, {"detail": NOT_ALLOWED})
    _, session = _http(live.port, "GET", f"/api/sessions/{live.session_id}", f"{LOOPBACK}:{live.port}")
    assert session["state"] == "running" and session["settings"]["torque_gain"] == 1.0


@pytest.mark.parametrize("path", ["/ws/devices/{sid}", "/ws/sessions/{sid}"])
def test_rebound_websockets_are_refused(live: Live, path: str) -> None:
    forged = f"{EVIL}:{live.port}"
    with pytest.raises(InvalidStatus) as exc:
        _ws(live.port, path.format(sid=live.session_id), forged, f"http://{forged}")
    assert exc.value.response.status_code == 403  # the ASGI server's answer to close 1008 before accept
    with pytest.raises(InvalidStatus) as exc:  # no Origin (a script): still the wrong host
        _ws(live.port, path.format(sid=live.session_id), forged, None)
    assert exc.value.response.status_code == 403


def test_request_without_host_is_refused(live: Live) -> None:
    with socket.create_connection((LOOPBACK, live.port), timeout=10) as s:
        s.sendall(b"GET /api/sessions HTTP/1.0\r\n\r\n")
        answer = b""
        while chunk := s.recv(65536):
            answer += chunk
    head, _, body = answer.partition(b"\r\n\r\n")
    assert head.split(b" ")[1] == b"400"
    assert json.loads(body) == {"detail": "request has no Host header"}


@pytest.mark.parametrize("name", ALLOWED)
def test_allowed_hosts_read_write_and_stream(live: Live, name: str) -> None:
    host, sid = f"{name}:{live.port}", live.session_id
    status, sessions = _http(live.port, "GET", "/api/sessions", host)
    assert status == 200 and [s["id"] for s in sessions] == [sid]
    status, _ = _http(live.port, "GET", "/", name)  # any port, or none
    assert status == 200
    event = {"text": f"from {name}"}
    status, _ = _http(live.port, "POST", f"/api/sessions/{sid}/annotations", host, f"http://{host}", event)
    assert status == 201
    token = issue_token(f"http://{LOOPBACK}:{live.port}", sid)
    with _ws(live.port, f"/ws/devices/{sid}?token={token}", host, f"http://{host}") as ws:
        ws.send(json.dumps({"type": "frame", "seq": 0, "t": 0.0, "foot_angle_deg": 5.0}))
        assert json.loads(ws.recv(timeout=10))["type"] == "torque"
    with _ws(live.port, f"/ws/sessions/{sid}", host, f"http://{host}") as ws:
        assert json.loads(ws.recv(timeout=10))["type"] == "hello"


def test_allowed_host_from_another_site_is_still_refused(live: Live) -> None:
    host = f"{LOOPBACK}:{live.port}"
    status, body = _http(live.port, "POST", f"/api/sessions/{live.session_id}/stop", host, f"http://{EVIL}")
    assert (status, body) == (403, {"detail": f"cross-origin request from http://{EVIL} refused"})


# --- the leg view's port -------------------------------------------------------------------------


def test_leg_view_refuses_a_rebound_host(live: Live) -> None:
    forged = f"{EVIL}:{live.viser_port}"
    assert _http(live.viser_port, "GET", "/", forged, f"http://{forged}") == (400, (NOT_ALLOWED + "\n").encode())
    with pytest.raises(InvalidStatus) as exc:
        _ws(live.viser_port, "/", forged, f"http://{forged}")
    assert exc.value.response.status_code == 400
    assert exc.value.response.body == (NOT_ALLOWED + "\n").encode()


def test_leg_view_refuses_a_websocket_from_another_site(live: Live) -> None:
    with pytest.raises(InvalidStatus) as exc:
        _ws(live.viser_port, "/", f"{LOOPBACK}:{live.viser_port}", f"http://{EVIL}")
    assert exc.value.response.status_code == 403
    assert exc.value.response.body == f"cross-origin request from http://{EVIL} refused\n".encode()


@pytest.mark.parametrize("name", ALLOWED)
def test_leg_view_serves_allowed_hosts(live: Live, name: str) -> None:
    host = f"{name}:{live.viser_port}"
    status, page = _http(live.viser_port, "GET", "/", host)
    assert status == 200 and b"<html" in page.lower()
    protocol = Subprotocol(f"viser-v{viser.__version__}")
    with _ws(live.viser_port, "/", host, f"http://{host}", subprotocols=[protocol]) as ws:
        assert isinstance(ws.recv(timeout=10), bytes)  # the scene, as the viewer page gets it


# --- wiring and settings -------------------------------------------------------------------------


def test_leg_view_binds_the_servers_host_with_its_allowlist(tmp_path: Path) -> None:
    settings = Settings(data_dir=tmp_path, demo=False, viser_port=0, allowed_hosts=["testserver", "gait.lab"])
    with TestClient(create_app(settings)) as client:
        view = client.app.state.ctx.leg_view  # type: ignore[attr-defined]
        assert isinstance(view, LegView)
        assert view.server.get_host() == settings.host == LOOPBACK
        assert view.allowed_hosts == settings.allowed_hosts == ["testserver", "gait.lab", LOOPBACK]


def test_leg_view_will_not_start_without_its_guard(monkeypatch: pytest.MonkeyPatch) -> None:
    @contextlib.contextmanager
    def bypassed(allowed_hosts: Any, logged_in: Any = None, watch: Any = None) -> Iterator[list[int]]:
        yield []  # as if viser served some other way: the guard never went in

    monkeypatch.setattr(gaitscope.server.leg_view, "_guarded_serve", bypassed)
    with pytest.raises(RuntimeError, match="no host guard"):
        LegView(port=0)


def test_leg_view_with_accounts_refuses_a_websocket_without_a_login() -> None:
    view = LegView(port=0, logged_in=lambda cookie: "gaitscope_login=open" in cookie)
    try:
        host = f"{LOOPBACK}:{view.port}"
        protocol = Subprotocol(f"viser-v{viser.__version__}")
        for cookie in (None, "gaitscope_login=ended"):
            headers = {} if cookie is None else {"Cookie": cookie}
            with pytest.raises(InvalidStatus) as exc:
                _ws(view.port, "/", host, f"http://{host}", subprotocols=[protocol], additional_headers=headers)
            assert exc.value.response.status_code == 401
        headers = {"Cookie": "theme=dark; gaitscope_login=open"}
        with _ws(view.port, "/", host, f"http://{host}", subprotocols=[protocol], additional_headers=headers) as ws:
            assert isinstance(ws.recv(timeout=10), bytes)
    finally:
        view.close()


def test_guard_is_only_installed_while_viser_starts() -> None:
    import websockets.asyncio.server

    before = websockets.asyncio.server.serve
    view = LegView(port=0)
    view.close()
    assert websockets.asyncio.server.serve is before


def test_default_allowlist_is_loopback_plus_the_bind_host(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("GAITSCOPE_ALLOWED_HOSTS", raising=False)
    assert Settings().allowed_hosts == ["127.0.0.1", "localhost", "::1"]
    network = {"auth": True, "behind_tls_proxy": True}  # what a bind beyond loopback needs
    assert Settings(host="0.0.0.0", **network).allowed_hosts == ["127.0.0.1", "localhost", "::1"]
    wanted = ["127.0.0.1", "localhost", "::1", "192.168.1.20"]
    assert Settings(host="192.168.1.20", **network).allowed_hosts == wanted
    assert "testserver" not in Settings().allowed_hosts


def test_allowlist_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("GAITSCOPE_ALLOWED_HOSTS", " Gait.Lab, [::1] ,")
    assert Settings().allowed_hosts == ["gait.lab", "::1", "127.0.0.1"]  # the bind host is always served
    for bad in ("*", "gait.lab:8000", "http://gait.lab"):
        monkeypatch.setenv("GAITSCOPE_ALLOWED_HOSTS", bad)
        with pytest.raises(ValidationError, match="is not a host name or address"):
            Settings()
