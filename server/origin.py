"""Who may talk to the server: an allowlist of host names, and the same-origin rule for changes.

Two guards, both ASGI middleware, and the same two rules for the viser leg view's own server
(:func:`websockets_guard`, a ``process_request`` hook for the ``websockets`` library):

**Allowed hosts** (:class:`AllowedHostsMiddleware`), every HTTP request and websocket. A page on
``evil.example`` can make the clinician's browser re-resolve ``evil.example`` to 127.0.0.1 (DNS
rebinding); it is then same-origin with this server, and reads patient data and opens device sockets
as if it were the dashboard. The browser still sends ``Host: evil.example``, so any request whose Host
names a host outside the allowlist (``Settings.allowed_hosts``) is refused: 400 over HTTP, close 1008
for a websocket (which the ASGI server turns into a 403 handshake response). The rule:

- the *name* must be on the list; the port is not checked, since the leg view is on another port of
  the same names and the port is not what rebinding controls;
- names compare case-insensitively; IPv6 literals compare in their canonical form, with or without
  brackets on the list (the header must bracket them, as RFC 3986 says);
- a request without exactly one ``Host`` header is refused: browsers always send one, HTTP/1.1 makes
  it mandatory, and a request that names no host, or two, is not worth guessing about.

**Same origin** (:class:`SameOriginMiddleware`), requests that change state. A page from another
site can reach a server on 127.0.0.1 without rebinding: body-less POSTs (``/stop``, ``/start``) need
no CORS preflight, and websockets are not covered by CORS at all, so such a page could stop a session
or push sensor frames that drive the torque command. Browsers always send ``Origin`` on those
requests; every method but GET, HEAD and OPTIONS, and every websocket, whose ``Origin`` is not the
server's own is refused with 403 (close 1008). The server's own origin is the scheme it was reached by
(``http`` or ``https``; ``ws``/``wss`` count as those; behind a TLS proxy, the scheme the proxy forwards)
and the ``Host`` it was reached at, a scheme's default port (80, 443) written or not: a page served
over plain HTTP under the same name (one a network attacker injected) is another origin than the
HTTPS dashboard. Clients that are not browsers (devices, scripts) send no ``Origin`` and are unaffected.

Why not starlette's ``TrustedHostMiddleware``: it does cover websockets, but refuses them with an
HTTP denial response rather than the close code the other guard uses, answers a bare "Invalid host
header", and its host parsing is private to starlette; the leg view's server is not ASGI and must
apply the very same rule, so the rule lives here, once.
"""

from __future__ import annotations

import ipaddress
import json
import logging
import re
from collections.abc import Awaitable, Callable, Collection, Iterable, Sequence
from http import HTTPStatus
from urllib.parse import urlsplit

from starlette.types import ASGIApp, Receive, Scope, Send
from websockets.asyncio.server import ServerConnection
from websockets.http11 import Request, Response

__all__ = [
    "LOOPBACK_HOSTS",
    "AllowedHostsMiddleware",
    "SameOriginMiddleware",
    "allowed_host",
    "allowed_hosts_for",
    "cross_origin",
    "host_name",
    "refused_host",
    "websockets_guard",
]

log = logging.getLogger("gaitscope")

#: The loopback names; the default allowlist (an attacker's page can never be served from them).
LOOPBACK_HOSTS: tuple[str, ...] = ("127.0.0.1", "localhost", "::1")
#: Bind addresses meaning "every interface": not a name anyone reaches the server at.
WILDCARD_BINDS = frozenset({"", "0.0.0.0", "::"})
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
#: A registered name or an IPv4 address (RFC 3986 reg-name, less percent-encoding and sub-delims).
_NAME = re.compile(r"[a-z0-9._~-]+")
_PORT = re.compile(r"[0-9]*")
_WS_REASON_BYTES = 123  # a close frame's reason, at most (RFC 6455 5.5)

#: A ``websockets`` ``process_request`` hook: an HTTP response refuses the handshake, None lets it go on.
ProcessRequest = Callable[[ServerConnection, Request], "Response | Awaitable[Response | None] | None"]


def _ipv6(text: str) -> str | None:
    try:
        return ipaddress.IPv6Address(text).compressed
    except ValueError:
        return None


def allowed_host(entry: str) -> str:
    """An allowlist entry in its canonical form: a lower-case name, or an IPv6 literal unbracketed.

    Raises:
        ValueError: not a bare host name or address (a scheme, a port, a path or a wildcard).
    """
    text = entry.strip().lower()
    v6 = _ipv6(text[1:-1] if text.startswith("[") and text.endswith("]") else text)
    if v6 is not None:
        return v6
    if not _NAME.fullmatch(text):
        raise ValueError(f"allowed host {entry!r} is not a host name or address (no scheme, port or wildcard)")
    return text


def allowed_hosts_for(bind_host: str, names: Iterable[str] = LOOPBACK_HOSTS) -> list[str]:
    """``names`` in canonical form, plus ``bind_host`` unless it is a wildcard; no duplicates, in order."""
    entries = [*names] + ([] if bind_host in WILDCARD_BINDS else [bind_host])
    return list(dict.fromkeys(allowed_host(e) for e in entries))


def host_name(header: str) -> str | None:
    """The host name a ``Host`` header names, canonical as :func:`allowed_host`; None if malformed.

    ``name``, ``name:port``, ``[v6]`` and ``[v6]:port``; the port is dropped.
    """
    text = header.strip().lower()
    if text.startswith("["):
        inside, bracket, port = text[1:].partition("]")
        if not bracket or not (port == "" or (port.startswith(":") and _PORT.fullmatch(port[1:]))):
            return None
        return _ipv6(inside)
    name, _, port = text.partition(":")
    if not _NAME.fullmatch(name) or not _PORT.fullmatch(port):
        return None
    return name


def refused_host(hosts: Sequence[str], allowed: Collection[str]) -> str | None:
    """Why a request with these ``Host`` header values is refused, or None when its host is allowed.

    Args:
        hosts: every ``Host`` header of the request (one, normally).
        allowed: canonical names (:func:`allowed_host`).
    """
    if len(hosts) != 1:
        return "a request must have exactly one Host header" if hosts else "request has no Host header"
    name = host_name(hosts[0])
    if name is None:
        return f"malformed Host header {hosts[0][:60]!a}"
    if name not in allowed:
        return f"host {name[:60]!a} is not allowed (add it to GAITSCOPE_ALLOWED_HOSTS to serve it)"
    return None


#: The port a scheme means when none is written.
_DEFAULT_PORTS = {"http": ":80", "https": ":443"}
#: The scheme of a request's origin, by the scheme of the request (ASGI ``scope["scheme"]``).
_ORIGIN_SCHEMES = {"http": "http", "ws": "http", "https": "https", "wss": "https"}


def _netloc(netloc: str, scheme: str) -> str:
    text = netloc.strip().lower()
    default = _DEFAULT_PORTS.get(scheme, "")
    return text[: -len(default)] if default and text.endswith(default) else text


def _cross_origin(origin: str | None, host: str | None, scheme: str = "http") -> str | None:
    """``origin`` if it is not ``scheme://host`` (the server's own origin), else None; None without an origin.

    ``scheme``: ``http`` or ``https`` (``ws``/``wss`` are read as those).
    """
    if origin is None:
        return None
    own = _ORIGIN_SCHEMES.get(scheme.lower(), scheme.lower())
    parts = urlsplit(origin.strip())
    if host is not None and parts.scheme.lower() == own and _netloc(parts.netloc, own) == _netloc(host, own):
        return None
    return origin


def _headers(scope: Scope, name: bytes) -> list[str]:
    return [value.decode("latin-1") for key, value in scope.get("headers", []) if key == name]


def _header(scope: Scope, name: bytes) -> str | None:
    values = _headers(scope, name)
    return values[0] if values else None


def cross_origin(scope: Scope) -> str | None:
    """The offending origin if this request changes state from another site, else None."""
    if scope["type"] == "http" and scope.get("method") in SAFE_METHODS:
        return None
    return _cross_origin(_header(scope, b"origin"), _header(scope, b"host"), str(scope.get("scheme", "http")))


async def _refuse(scope: Scope, send: Send, status: int, reason: str) -> None:
    """Close a websocket with 1008, or answer HTTP ``status`` with ``{"detail": reason}``."""
    log.warning("refused %s %s: %s", scope["type"], scope.get("path", ""), reason)
    if scope["type"] == "websocket":
        short = reason.encode()[:_WS_REASON_BYTES].decode(errors="ignore")
        await send({"type": "websocket.close", "code": 1008, "reason": short})
        return
    body = json.dumps({"detail": reason}).encode()
    headers = [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": body})


class AllowedHostsMiddleware:
    """Refuses every HTTP request and websocket whose ``Host`` names a host not in ``allowed_hosts``.

    Args:
        app: the app behind the guard.
        allowed_hosts: names and addresses, without ports (:func:`allowed_host` forms).
    """

    def __init__(self, app: ASGIApp, allowed_hosts: Iterable[str]) -> None:
        self.app = app
        self.allowed_hosts = frozenset(allowed_host(h) for h in allowed_hosts)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] in ("http", "websocket"):
            reason = refused_host(_headers(scope, b"host"), self.allowed_hosts)
            if reason is not None:
                await _refuse(scope, send, 400, reason)
                return
        await self.app(scope, receive, send)


class SameOriginMiddleware:
    """Refuses requests that change state (and every websocket) from a foreign ``Origin``."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] in ("http", "websocket"):
            origin = cross_origin(scope)
            if origin is not None:
                await _refuse(scope, send, 403, f"cross-origin request from {origin[:100]} refused")
                return
        await self.app(scope, receive, send)


def websockets_guard(allowed_hosts: Iterable[str], then: ProcessRequest | None = None) -> ProcessRequest:
    """Both rules as a ``process_request`` hook for a ``websockets`` server (the viser leg view).

    Every request (the viewer's static files as well as its websocket) must name an allowed host
    (else 400); a websocket upgrade must also come from no origin or its own (else 403). Refusals
    answer the handshake with a plain-text reason; what passes goes on to ``then``, if any.

    The server's own scheme is ``http`` (viser speaks no TLS), or what a TLS proxy in front says in
    ``X-Forwarded-Proto`` (``https``): a browser's websocket cannot set that header, so a page cannot
    claim the scheme of another origin with it.
    """
    allowed = frozenset(allowed_host(h) for h in allowed_hosts)

    def process_request(connection: ServerConnection, request: Request) -> Response | Awaitable[Response | None] | None:
        hosts = request.headers.get_all("Host")
        reason = refused_host(hosts, allowed)
        status = HTTPStatus.BAD_REQUEST
        upgrade = any("websocket" in u.lower() for u in request.headers.get_all("Upgrade"))
        if reason is None and upgrade:
            origins = request.headers.get_all("Origin")
            forwarded = request.headers.get("X-Forwarded-Proto", "http").split(",")[0].strip() or "http"
            origin = _cross_origin(", ".join(origins) or None, hosts[0], forwarded)  # two origins never match
            if origin is not None:
                reason, status = f"cross-origin request from {origin[:100]} refused", HTTPStatus.FORBIDDEN
        if reason is not None:
            log.warning("refused leg view request %s: %s", request.path[:100], reason)
            return connection.respond(status, reason + "\n")
        return None if then is None else then(connection, request)

    return process_request
