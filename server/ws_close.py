"""Closing a websocket whose client stopped reading, with the close code it deserves.

A browser stream that cannot keep up is closed with 1013 (try again later) and the reason
(:mod:`gaitscope.server.routes.streams`). But a client that has stopped reading altogether has filled the socket's
buffers, and the ASGI server then holds every ``send`` back, the close frame too (uvicorn waits for the
transport to be writable again, which it never is): the close never left, the server's own keepalive (or
the client's) later failed the connection with 1011 "keepalive ping timeout", and that is what the client
saw (issue #21).

So the close is tried through ASGI for a moment; if it cannot be sent, it is written straight to the
connection, behind what is already buffered, through the server's own protocol object: a client that
reads again gets what was sent, then 1013 with the reason. If it still does not read within ``grace_s``
(:data:`ABORT_AFTER_S`), the connection is aborted, so that it holds no memory. A client that never reads
again sees no close code at all, whatever the server does: its own keepalive, if it has one, ends it.

:class:`ServerSendMiddleware` (outermost) keeps the server's own ``send`` in the scope for this; only
uvicorn's ``websockets-sansio`` protocol (the one ``gaitscope serve`` runs) is known, and anything else
gets the ASGI close alone.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from typing import Any, Final

from starlette.types import ASGIApp, Receive, Scope, Send
from starlette.websockets import WebSocket

__all__ = ["ABORT_AFTER_S", "SERVER_SEND", "ServerSendMiddleware", "close_stuck"]

log = logging.getLogger("gaitscope")

#: Scope key of the ASGI server's own ``send`` (before any middleware wrapped it).
SERVER_SEND: Final = "gaitscope.server_send"
#: Seconds a connection closed past its buffers is kept for its client to read to the close frame: longer than
#: a keepalive's ping interval and timeout (20 s + 20 s, uvicorn's and the websockets library's defaults).
ABORT_AFTER_S: Final = 60.0


class ServerSendMiddleware:
    """Keeps the server's ``send`` of each websocket in its scope (:data:`SERVER_SEND`); add it last (outermost)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "websocket":
            scope[SERVER_SEND] = send
        await self.app(scope, receive, send)


def _write_close(scope: Scope, code: int, reason: str, grace_s: float) -> bool:
    """Write the close frame to the connection directly (uvicorn's websockets-sansio protocol); False if the
    server is another one, or the connection is already closing."""
    protocol: Any = getattr(scope.get(SERVER_SEND), "__self__", None)
    conn, transport = getattr(protocol, "conn", None), getattr(protocol, "transport", None)
    if conn is None or transport is None or not hasattr(conn, "send_close") or transport.is_closing():
        return False
    try:
        conn.send_close(code, reason)
        transport.write(b"".join(conn.data_to_send()))
    except Exception:  # an unknown state of the protocol: leave it to the ASGI close
        log.exception("could not write the close frame of %s", scope.get("path", "")[:100])
        return False
    protocol.close_sent = True  # the server sends nothing more, and the closing handshake is ours
    transport.close()  # sends what is buffered, the close frame last, then closes
    asyncio.get_running_loop().call_later(grace_s, transport.abort)  # unless the client never reads
    return True


async def close_stuck(
    ws: WebSocket, code: int, reason: str, *, wait_s: float = 1.0, grace_s: float = ABORT_AFTER_S
) -> str:
    """Close ``ws`` with ``code`` and ``reason`` even if its client stopped reading; returns how: ``"asgi"``
    (sent normally within ``wait_s``), ``"direct"`` (written behind the buffered data; aborted after ``grace_s``
    if the client still does not read) or ``"none"`` (neither: the connection was gone, or the server unknown)."""
    reason = reason.encode()[:123].decode(errors="ignore")  # a close frame's reason, at most (RFC 6455 5.5)
    try:
        await asyncio.wait_for(ws.close(code=code, reason=reason), timeout=wait_s)
        return "asgi"
    except TimeoutError:
        pass
    except Exception:  # the connection is already gone: nothing to say it on
        return "none"
    with contextlib.suppress(Exception):
        if _write_close(ws.scope, code, reason, grace_s):
            return "direct"
    return "none"
