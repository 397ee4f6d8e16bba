"""Requests that change state from another site are refused; same-site and non-browser ones are not.
Requests naming a host outside the allowlist (DNS rebinding) are refused, whatever they do."""

from __future__ import annotations

import asyncio
import functools
import json
from typing import Any

import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from gaitscope.server.origin import (
    LOOPBACK_HOSTS,
    AllowedHostsMiddleware,
    SameOriginMiddleware,
    allowed_host,
    allowed_hosts_for,
    cross_origin,
    host_name,
    refused_host,
    websockets_guard,
)
from tests.device_tokens import device_path

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
    assert (
        client.patch(
            f"/api/sessions/{sid}/settings", json={"torque_gain": 1.2, "confirm": True}, headers=same
        ).status_code
        == 200
    )
    with client.websocket_connect(device_path(client, sid)) as ws:  # a device sends no Origin
        ws.send_json({"type": "frame", "seq": 0, "t": 0.0, "foot_angle_deg": 5.0})
        assert ws.receive_json()["type"] == "torque"
    assert client.post(f"/api/sessions/{sid}/stop", headers=same).status_code == 200


# --- allowed hosts -------------------------------------------------------------------------------

REBOUND = {"host": "evil.example:8000", "origin": "http://evil.example:8000"}  # DNS rebinding: both agree
NOT_ALLOWED = "host 'evil.example' is not allowed (add it to GAITSCOPE_ALLOWED_HOSTS to serve it)"


def test_rebound_host_is_refused_for_reads_writes_and_websockets(client: TestClient) -> None:
    sid = _session(client)
    r = client.get("/api/sessions", headers=REBOUND)
    assert r.status_code == 400 and r.json() == {"detail": NOT_ALLOWED}
    r = client.patch(f"/api/sessions/{sid}/settings", json={"torque_gain": 1.2, "confirm": True}, headers=REBOUND)
    assert r.status_code == 400 and r.json() == {"detail": NOT_ALLOWED}
    assert client.get(f"/api/sessions/{sid}").json()["settings"]["torque_gain"] == 1.0
    for path in (f"/ws/devices/{sid}", f"/ws/sessions/{sid}"):
        with pytest.raises(WebSocketDisconnect) as exc, client.websocket_connect(path, headers=REBOUND):
            pass
        assert (exc.value.code, exc.value.reason) == (1008, NOT_ALLOWED)


def test_allowed_host_passes_whatever_its_port(client: TestClient) -> None:
    assert client.get("/api/sessions", headers={"host": "TestServer:1234"}).status_code == 200


@pytest.mark.parametrize(
    ("header", "name"),
    [
        ("127.0.0.1:8000", "127.0.0.1"),
        ("LocalHost", "localhost"),
        ("localhost:", "localhost"),
        ("[::1]:8081", "::1"),
        ("[0:0::1]", "::1"),
        ("gait.lab", "gait.lab"),
        ("::1", None),  # IPv6 must be bracketed in a Host header
        ("[::1", None),
        ("[::1]x", None),
        ("[evil.example]", None),
        ("evil.example:80x", None),
        ("evil example", None),
        ("user@evil.example", None),
        ("", None),
    ],
)
def test_host_name_of_a_host_header(header: str, name: str | None) -> None:
    assert host_name(header) == name


def test_allowlist_entries_are_canonical_and_bare() -> None:
    assert [allowed_host(h) for h in ("LOCALHOST", " [::1] ", "::1", "0:0::1", "10.0.0.7")] == [
        "localhost", "::1", "::1", "::1", "10.0.0.7",
    ]  # fmt: skip
    for bad in ("*", "*.example.com", "gait.lab:8000", "http://gait.lab", "gait.lab/", "[gait.lab]", ""):
        with pytest.raises(ValueError, match="is not a host name or address"):
            allowed_host(bad)
    assert allowed_hosts_for("127.0.0.1") == list(LOOPBACK_HOSTS) == ["127.0.0.1", "localhost", "::1"]
    assert allowed_hosts_for("0.0.0.0") == allowed_hosts_for("::") == list(LOOPBACK_HOSTS)
    assert allowed_hosts_for("Gait.Lab", ["[::1]"]) == ["::1", "gait.lab"]


def test_refused_host_reasons() -> None:
    allowed = {"localhost"}
    assert refused_host(["localhost:1"], allowed) is None
    assert refused_host([], allowed) == "request has no Host header"
    assert refused_host(["localhost", "evil.example"], allowed) == "a request must have exactly one Host header"
    assert refused_host(["a b"], allowed) == "malformed Host header 'a b'"
    assert refused_host(["évil.example"], allowed) == r"malformed Host header '\xe9vil.example'"


async def _asgi(middleware: Any, scope: dict[str, Any]) -> list[dict[str, Any]]:
    """Run ``middleware`` around an app that answers 200, and return what was sent."""
    sent: list[dict[str, Any]] = []

    async def app(scope: Any, receive: Any, send: Any) -> None:
        await send({"type": "http.response.start", "status": 200, "headers": []})

    async def receive() -> dict[str, Any]:  # pragma: no cover - never called
        raise AssertionError

    async def send(message: Any) -> None:
        sent.append(message)

    await middleware(app)(scope, receive, send)
    return sent


def test_requests_without_exactly_one_host_are_refused() -> None:
    guard = functools.partial(AllowedHostsMiddleware, allowed_hosts=["localhost"])
    http: dict[str, Any] = {"type": "http", "method": "GET", "path": "/api/sessions"}
    sent = asyncio.run(_asgi(guard, http | {"headers": []}))  # HTTP/1.0 without Host
    assert sent[0]["status"] == 400 and json.loads(sent[1]["body"]) == {"detail": "request has no Host header"}
    two = [(b"host", b"localhost"), (b"host", b"evil.example")]
    assert asyncio.run(_asgi(guard, http | {"headers": two}))[0]["status"] == 400
    assert asyncio.run(_asgi(guard, http | {"headers": [(b"host", b"localhost")]}))[0]["status"] == 200
    ws = {"type": "websocket", "path": "/ws/sessions/1", "headers": []}
    assert asyncio.run(_asgi(guard, ws)) == [
        {"type": "websocket.close", "code": 1008, "reason": "request has no Host header"}
    ]
    lifespan = {"type": "lifespan"}
    assert asyncio.run(_asgi(guard, lifespan))[0]["status"] == 200  # not a request: passed through


def test_close_reason_fits_a_close_frame() -> None:
    origin = "http://" + "é" * 200
    scope = {"type": "websocket", "path": "/ws/devices/1", "headers": [(b"host", b"x"), (b"origin", origin.encode())]}
    (close,) = asyncio.run(_asgi(SameOriginMiddleware, scope))
    assert close["code"] == 1008 and len(close["reason"].encode()) <= 123
    assert close["reason"].startswith("cross-origin request from http://Ã©")  # header bytes read as latin-1


# --- the scheme is part of the origin (issue #21) -------------------------------------------------------


@pytest.mark.parametrize(
    ("scheme", "origin", "refused"),
    [
        ("http", "http://gaitlab.local:8000", False),
        ("http", "https://gaitlab.local:8000", True),  # another origin: the scheme differs
        ("https", "https://gaitlab.local:8000", False),
        ("https", "http://gaitlab.local:8000", True),  # a plain-HTTP page (injected) under the HTTPS name
        ("ws", "http://gaitlab.local:8000", False),
        ("wss", "https://gaitlab.local:8000", False),
        ("wss", "http://gaitlab.local:8000", True),
        ("http", "HTTP://GAITLAB.LOCAL:8000", False),
        ("http", "http://gaitlab.local:8001", True),
        ("http", "null", True),
    ],
)
def test_the_origins_scheme_must_be_the_servers(scheme: str, origin: str, refused: bool) -> None:
    kind = "websocket" if scheme.startswith("ws") else "http"
    scope = {"type": kind, "scheme": scheme, "method": "POST", "path": "/api/x",
             "headers": [(b"host", b"gaitlab.local:8000"), (b"origin", origin.encode())]}  # fmt: skip
    assert (cross_origin(scope) is not None) == refused


@pytest.mark.parametrize(
    ("scheme", "host", "origin"),
    [("https", "gaitlab.local", "https://gaitlab.local:443"), ("https", "gaitlab.local:443", "https://gaitlab.local"),
     ("http", "gaitlab.local:80", "http://gaitlab.local")],
)  # fmt: skip
def test_a_schemes_default_port_written_or_not_is_the_same_origin(scheme: str, host: str, origin: str) -> None:
    scope = {"type": "http", "scheme": scheme, "method": "POST",
             "headers": [(b"host", host.encode()), (b"origin", origin.encode())]}  # fmt: skip
    assert cross_origin(scope) is None


def test_an_https_page_may_change_an_https_server_and_an_http_page_may_not(client: TestClient) -> None:
    sid = _session(client)
    with TestClient(client.app, base_url="https://testserver") as tls:  # the scheme a TLS proxy forwards
        r = tls.post(f"/api/sessions/{sid}/annotations", json={"text": "x"}, headers={"origin": "http://testserver"})
        assert r.status_code == 403 and r.json()["detail"] == "cross-origin request from http://testserver refused"
        r = tls.post(f"/api/sessions/{sid}/annotations", json={"text": "x"}, headers={"origin": "https://testserver"})
        assert r.status_code == 201, r.text
    r = client.post(f"/api/sessions/{sid}/annotations", json={"text": "x"}, headers={"origin": "https://testserver"})
    assert r.status_code == 403


def _handshake(guard: Any, headers: list[tuple[str, str]]) -> int | None:
    """The status the leg view's guard answers a websocket handshake with (None: let through)."""
    from websockets.datastructures import Headers
    from websockets.http11 import Request

    class _Connection:
        def respond(self, status: Any, text: str) -> Any:
            return int(status)

    request = Request("/websocket", Headers([("Host", "gaitlab.local:8081"), ("Upgrade", "websocket"), *headers]))
    return guard(_Connection(), request)  # type: ignore[no-any-return]


def test_the_leg_views_guard_takes_the_scheme_a_tls_proxy_forwards() -> None:
    guard = websockets_guard(["gaitlab.local"])
    assert _handshake(guard, [("Origin", "http://gaitlab.local:8081")]) is None
    assert _handshake(guard, [("Origin", "https://gaitlab.local:8081")]) == 403  # viser itself speaks no TLS
    behind = [("Origin", "https://gaitlab.local:8081"), ("X-Forwarded-Proto", "https")]
    assert _handshake(guard, behind) is None
    assert _handshake(guard, [("Origin", "http://gaitlab.local:8081"), ("X-Forwarded-Proto", "https")]) == 403
