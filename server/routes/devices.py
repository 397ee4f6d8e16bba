"""``/api/sessions/{id}/device-tokens``: the credentials of a session's device.

A device's websocket (``/ws/devices/{id}``) needs a token of its session, sent as ``Authorization: Bearer``
or as the ``token`` query parameter. A token is shown once, in the answer that issues it; the list shows
only its first characters. Revoking one refuses the next connection with it (a device already connected
is disconnected too, so that a lost tablet's token stops driving at once).
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path

from gaitscope.server.auth import Runner, allow
from gaitscope.server.routes.common import Ctx, Id, audit
from gaitscope.sessions import schema
from gaitscope.sessions.live.sources import LiveDevice

router = APIRouter(prefix="/api")

_TokenId = Annotated[int, Path(ge=1, le=schema.INT64_MAX)]


@router.post("/sessions/{session_id}/device-tokens", status_code=201)
def issue_token(session_id: Id, c: Ctx, who: Runner) -> schema.DeviceToken:
    session = c.store.get_session(session_id)
    if session.source.kind != "device":
        from gaitscope.sessions.store import Conflict

        raise Conflict(f"session {session_id} takes no device (source {session.source.kind})")
    audit(c, who, "device_token.issue", f"session {session_id}")
    return c.accounts.issue_device_token(session_id, by=who.name)


@router.get("/sessions/{session_id}/device-tokens", dependencies=[allow("read")])
def list_tokens(session_id: Id, c: Ctx) -> list[schema.DeviceToken]:
    c.store.get_session(session_id)
    return c.accounts.list_device_tokens(session_id)


@router.delete("/sessions/{session_id}/device-tokens/{token_id}")
def revoke_token(session_id: Id, token_id: _TokenId, c: Ctx, who: Runner) -> schema.DeviceToken:
    audit(c, who, "device_token.revoke", f"session {session_id} token {token_id}")
    revoked = c.accounts.revoke_device_token(session_id, token_id, by=who.name)
    runtime = c.manager.get(session_id)
    if runtime is not None and isinstance(runtime.source, LiveDevice):
        runtime.source.revoked.add(token_id)  # a device connected with it is disconnected at its next frame
    return revoked
