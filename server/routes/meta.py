"""``/api/health`` and ``/api/schema``: what the server is, and the JSON schema of every wire class."""

from __future__ import annotations

import uuid
from typing import Any, Final

from fastapi import APIRouter, Response

from gaitscope.server.auth import allow, public
from gaitscope.sessions import schema
from gaitscope.sessions.formats.models import gaitscope_version

router = APIRouter(prefix="/api")

#: Names this server process; a restarted server answers with another one, which is how the
#: dashboard's header tells "the server restarted" from "the network dropped for a moment".
INSTANCE: Final = uuid.uuid4().hex
_VERSION: Final = gaitscope_version()  # read once: importlib.metadata scans the path on every call


@router.get("/health", dependencies=[public()])
async def health(response: Response) -> dict[str, str]:
    """``status`` (always ``"ok"`` when it answers), ``version`` and ``instance`` (see :data:`INSTANCE`).

    The dashboard polls it every second: never cached, and answered on the event loop (no thread hop).
    """
    response.headers["Cache-Control"] = "no-store"
    return {"status": "ok", "version": _VERSION, "instance": INSTANCE}


@router.get("/schema", dependencies=[allow("read")])
def wire_schema() -> dict[str, Any]:
    """JSON schema of every message that crosses a socket or a file."""
    return {cls.__name__: cls.model_json_schema() for cls in schema.WIRE}
