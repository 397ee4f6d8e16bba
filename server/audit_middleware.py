"""Refused requests into the audit trail: every state-changing request answered 401, 403, 409 or 422.

Issue #13 asks that refusals of state changes be audited as well as the changes themselves: a run of 403s is
someone trying what their role may not, a run of 409s a device or a script fighting the session's state. The
routes cannot do it (a refusal may come from the role guard, the CSRF check, the same-origin rule or request
validation, before any route code runs), so an ASGI middleware looks at the answer instead.

For an HTTP request whose method is not GET, HEAD or OPTIONS, when the response's status is one of
:data:`REFUSED`, the middleware holds the response back (its start and its body, up to :data:`BODY_MAX` bytes:
error bodies are small), writes the entry, then sends what it held. The entry: action ``refused METHOD
/route/{template}`` (the path when no route matched), target the path, outcome ``refused``, detail the status
and, for a JSON body, its ``detail`` in words (at most :data:`DETAIL_MAX` characters); user and role from the
:class:`gaitscope.server.auth.Who` the guard left in the scope, ``local``/``admin`` with accounts off, else
``anonymous``/``none``.

Everything else (websockets, lifespan, reads, answers with other statuses, streamed files) passes through
untouched. If the entry cannot be written (the database is down), the refusal is still sent and the failure is
logged: a refusal changes nothing, so there is nothing the entry would have to come before. A route that wrote
its refusal itself says so in the scope (:data:`AUDITED`), and nothing more is written.
"""

from __future__ import annotations

import json
import logging
from typing import TYPE_CHECKING, Any, Final

import anyio.to_thread
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from gaitscope.server.auth import LOCAL, Who
from gaitscope.server.origin import SAFE_METHODS

if TYPE_CHECKING:
    from gaitscope.sessions.audit import AuditLog

__all__ = ["AUDITED", "BODY_MAX", "DETAIL_MAX", "REFUSED", "AuditMiddleware"]

log = logging.getLogger("gaitscope")

#: The statuses that mean "refused": not logged in, not allowed, conflicts with the state, not acceptable.
REFUSED: Final = frozenset({401, 403, 409, 422})
#: Scope key a route sets (to True) when it has written its refusal to the trail itself (a failed login, with
#: the name tried): the middleware then writes nothing more.
AUDITED: Final = "gaitscope.audited"
#: The most of a refusal's body held back to read its ``detail``; past that it is sent on without it.
BODY_MAX: Final = 64 * 1024
#: The longest ``detail`` text kept from a refusal's body.
DETAIL_MAX: Final = 500


def _detail_text(body: bytes, content_type: str) -> str:
    """The ``detail`` of a JSON error body in words: a string as it is, pydantic's error list as
    ``loc: msg; loc: msg``; "" for anything else."""
    if "json" not in content_type:
        return ""
    try:
        detail = json.loads(body).get("detail")
    except (ValueError, AttributeError):
        return ""
    if isinstance(detail, str):
        return detail
    if isinstance(detail, list):
        parts = []
        for d in detail:
            if isinstance(d, dict):
                loc = ".".join(str(x) for x in d.get("loc", ()))
                parts.append(f"{loc}: {d.get('msg', '')}" if loc else str(d.get("msg", "")))
            else:
                parts.append(str(d))
        return "; ".join(parts)
    return "" if detail is None else json.dumps(detail)


def _who(scope: Scope, auth: bool) -> tuple[str, str]:
    who = scope.get("gaitscope.who")
    if isinstance(who, Who):
        return who.name, who.role
    if not auth:
        return LOCAL.name, LOCAL.role
    return "anonymous", "none"


class AuditMiddleware:
    """Writes refused state-changing requests to ``app.state.ctx.audit`` (see the module's docstring)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] in SAFE_METHODS:
            await self.app(scope, receive, send)
            return
        held: list[Message] = []
        size = 0
        status = 0
        passing = False  # the answer is not a refusal, or the refusal has been recorded: send as it comes

        async def flush() -> None:
            nonlocal passing
            passing = True
            body = b"".join(m.get("body", b"") for m in held if m["type"] == "http.response.body")
            await self._record(scope, status, body, _content_type(held[0]))
            for m in held:
                await send(m)
            held.clear()

        async def audited_send(message: Message) -> None:
            nonlocal size, status, passing
            if passing:
                await send(message)
            elif message["type"] == "http.response.start":
                status = int(message["status"])
                if status not in REFUSED:
                    passing = True
                    await send(message)
                else:
                    held.append(message)
            elif message["type"] == "http.response.body":
                held.append(message)
                size += len(message.get("body", b""))
                if not message.get("more_body", False) or size > BODY_MAX:
                    await flush()
            else:  # anything else (a zero-copy file send, trailers): record, then let it through
                await flush()
                await send(message)

        await self.app(scope, receive, audited_send)

    async def _record(self, scope: Scope, status: int, body: bytes, content_type: str) -> None:
        if scope.get(AUDITED):
            return
        ctx = getattr(scope["app"].state, "ctx", None)
        audit: AuditLog | None = getattr(ctx, "audit", None)
        if ctx is None or audit is None:
            log.warning("refused %s %s not audited: the app has no audit trail", scope["method"], scope["path"][:200])
            return
        route = scope.get("route")
        template = getattr(route, "path", None) or scope["path"]
        user, role = _who(scope, bool(ctx.settings.auth))
        text = _detail_text(body, content_type) if len(body) <= BODY_MAX else ""
        detail = f"{status}: {text}" if text else str(status)
        entry: dict[str, Any] = {
            "user": user,
            "role": role,
            "action": f"refused {scope['method']} {template}"[:128],
            "target": scope["path"],
            "outcome": "refused",
            "detail": detail[: len(str(status)) + 2 + DETAIL_MAX],
        }
        try:
            await anyio.to_thread.run_sync(lambda: audit.record(**entry))
        except Exception:  # the refusal must still be sent; see the module's docstring
            log.exception("could not write refused %s %s to the audit trail", scope["method"], scope["path"][:200])


def _content_type(start: Message) -> str:
    for name, value in start.get("headers", ()):
        if name.lower() == b"content-type":
            return bytes(value).decode("latin-1").lower()
    return ""
