"""The device protocol as machine-readable files, generated from the one schema module (``gaitscope device-spec``).

``docs/device_protocol/``: an AsyncAPI 2.6 document (``asyncapi.json``: the channel ``/ws/devices/{session_id}``,
its token, what a device publishes and what it receives) and a JSON Schema per message (``SensorFrame``,
``TorqueCommand``, ``DeviceNotice``), each from :mod:`gaitscope.sessions.schema`'s pydantic class, so a device team
can generate its client's types or validate its frames with their own tools. A test keeps the files in step with
the schema (``tests/server/test_device_spec.py``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Final

from pydantic import BaseModel

from gaitscope.sessions import schema

__all__ = ["MESSAGES", "render", "write"]

#: The messages on a device's socket: name -> (class, direction as AsyncAPI sees the server).
MESSAGES: Final[dict[str, tuple[type[BaseModel], str]]] = {
    "SensorFrame": (schema.SensorFrame, "publish"),
    "TorqueCommand": (schema.TorqueCommand, "subscribe"),
    "DeviceNotice": (schema.DeviceNotice, "subscribe"),
}


def _asyncapi(version: str) -> dict[str, Any]:
    messages = {
        name: {
            "name": name,
            "contentType": "application/json",
            "summary": (cls.__doc__ or "").strip().splitlines()[0],
            "payload": {"$ref": f"./{name}.schema.json"},
        }
        for name, (cls, _) in MESSAGES.items()
    }
    return {
        "asyncapi": "2.6.0",
        "info": {
            "title": "gaitscope device protocol",
            "version": version,
            "description": "A live device sends sensor frames and gets a torque command (or a notice) for each; "
            "docs/api.md, 'Device websocket', says every rule (rates, limits, notices, close codes).",
        },
        "servers": {
            "gaitscope": {
                "url": "{host}",
                "protocol": "ws",
                "variables": {"host": {"default": "localhost:8000"}},
                "security": [{"deviceToken": []}],
            }
        },
        "channels": {
            "/ws/devices/{session_id}": {
                "parameters": {"session_id": {"schema": {"type": "integer", "minimum": 1}}},
                "publish": {
                    "summary": "what the device sends",
                    "message": {"$ref": "#/components/messages/SensorFrame"},
                },
                "subscribe": {
                    "summary": "what the device receives, one per frame",
                    "message": {
                        "oneOf": [
                            {"$ref": "#/components/messages/TorqueCommand"},
                            {"$ref": "#/components/messages/DeviceNotice"},
                        ]
                    },
                },
            }
        },
        "components": {
            "messages": messages,
            "securitySchemes": {
                "deviceToken": {
                    "type": "httpBearerToken",
                    "description": "a token of the session (POST /api/sessions/{id}/device-tokens), as "
                    "'Authorization: Bearer <token>' or '?token=<token>'",
                }
            },
        },
    }


def render(version: str = "2") -> dict[str, str]:
    """File name -> text of every file of the spec."""
    files = {"asyncapi.json": _asyncapi(version)}
    for name, (cls, _) in MESSAGES.items():
        draft = "https://json-schema.org/draft/2020-12/schema"
        files[f"{name}.schema.json"] = {"$schema": draft, **cls.model_json_schema()}
    return {k: json.dumps(v, indent=2, sort_keys=True) + "\n" for k, v in files.items()}


def write(out: Path) -> list[Path]:
    """Write the files into ``out``; the ones that changed."""
    out.mkdir(parents=True, exist_ok=True)
    changed = []
    for name, text in render().items():
        path = out / name
        if not path.exists() or path.read_text() != text:
            path.write_text(text)
            changed.append(path)
    return changed
