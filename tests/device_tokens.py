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


def device_session(base: str, code: str, rate_hz: float) -> tuple[int, str, int]:
    """A new subject ``code`` (0.9 m, 70 kg) of the real server at ``base`` (accounts off), a device session of it
    at ``rate_hz`` and a token issued for it: ``(session id, token, token id)``."""
    subject = _post(f"{base}/api/subjects", {"code": code, "leg_length_m": 0.9, "mass_kg": 70.0})
    session = _post(
        f"{base}/api/sessions", {"subject_id": subject["id"], "source": {"kind": "device", "rate_hz": rate_hz}}
    )
    token = _post(f"{base}/api/sessions/{session['id']}/device-tokens", None)
    return int(session["id"]), str(token["token"]), int(token["id"])


def _post(url: str, body: object) -> dict:  # type: ignore[type-arg]
    data = b"" if body is None else json.dumps(body).encode()
    req = urllib.request.Request(url, data=data, headers={"Content-Type": "application/json"}, method="POST")
    with urllib.request.urlopen(req, timeout=10) as r:
        return dict(json.loads(r.read()))
