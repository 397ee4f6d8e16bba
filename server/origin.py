"""Same-origin guard for everything that changes state.

A web page from another site, open in the clinician's browser, can reach a server on 127.0.0.1: body-less
POSTs (``/stop``, ``/start``) need no CORS preflight, and websockets are not covered by CORS at all, so
such a page could stop a session or push sensor frames that drive the torque command. Browsers always
send ``Origin`` on those requests; this middleware refuses any request that changes state (every method
but GET, HEAD and OPTIONS, and every websocket) whose ``Origin`` is not the server's own (the ``Host`` it
was reached at). Clients that are not browsers (devices, scripts) send no ``Origin`` and are unaffected.
"""

from __future__ import annotations

import json
from urllib.parse import urlsplit

from starlette.types import ASGIApp, Receive, Scope, Send

SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})


def _header(scope: Scope, name: bytes) -> str | None:
    for key, value in scope.get("headers", []):
        if key == name:
            return str(value.decode("latin-1"))
    return None


def cross_origin(scope: Scope) -> str | None:
    """The offending origin if this request changes state from another site, else None."""
    if scope["type"] == "http" and scope.get("method") in SAFE_METHODS:
        return None
    origin = _header(scope, b"origin")
    if origin is None:
        return None
    host = _header(scope, b"host")
    if host is not None and urlsplit(origin).netloc.lower() == host.lower():
        return None
    return origin


class SameOriginMiddleware:
    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] in ("http", "websocket"):
            origin = cross_origin(scope)
            if origin is not None:
                reason = f"cross-origin request from {origin} refused"
                if scope["type"] == "websocket":
                    await send({"type": "websocket.close", "code": 1008, "reason": reason[:120]})
                    return
                body = json.dumps({"detail": reason}).encode()
                await send(
                    {
                        "type": "http.response.start",
                        "status": 403,
                        "headers": [
                            (b"content-type", b"application/json"),
                            (b"content-length", str(len(body)).encode()),
                        ],
                    }
                )
                await send({"type": "http.response.body", "body": body})
                return
        await self.app(scope, receive, send)
