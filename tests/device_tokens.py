"""A device's way in for the tests: a token issued for its session, as a real device gets one."""

from __future__ import annotations

import json
import urllib.request

from fastapi.testclient import TestClient


def device_path(client: TestClient, session_id: int) -> str:
    """``/ws/devices/{id}?token=...`` with a token just issued for the session."""
    r = client.post(f"/api/sessions/{session_id}/device-tokens")
    assert r.status_code == 201, r.text
    return f"/ws/devices/{session_id}?token={r.json()['token']}"


def issue_token(base: str, session_id: int) -> str:
    """A token for session ``session_id`` of the real server at ``base`` (accounts off)."""
    req = urllib.request.Request(f"{base}/api/sessions/{session_id}/device-tokens", data=b"", method="POST")
    with urllib.request.urlopen(req, timeout=10) as r:
        return str(json.loads(r.read())["token"])
