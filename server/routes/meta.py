"""``/api/health`` and ``/api/schema``: what the server is, and the JSON schema of every wire class."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter

from sessions import schema
from sessions.formats.models import gaitscope_version

router = APIRouter(prefix="/api")


@router.get("/health")
def health() -> dict[str, str]:
    return {"status": "ok", "version": gaitscope_version()}


@router.get("/schema")
def wire_schema() -> dict[str, Any]:
    """JSON schema of every message that crosses a socket or a file."""
    return {cls.__name__: cls.model_json_schema() for cls in schema.WIRE}
