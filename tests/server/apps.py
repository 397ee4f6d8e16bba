"""The real app for the server tests: with accounts on (:func:`auth_settings`, :func:`login`), its routes
(:func:`app_routes`), a subject and a running simulated session (:func:`session`), and a device session
driven through the real runtime (:func:`recorded`). ``tests/conftest.py``'s ``client`` is the app with
accounts off."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from fastapi.testclient import TestClient

from gaitscope.server.auth import COOKIE, CSRF_HEADER
from gaitscope.server.settings import Settings
from gaitscope.sessions.live.runtime import SessionRuntime
from gaitscope.sessions.live.sources import LiveDevice
from gaitscope.sessions.schema import SensorFrame
from tests.waiting import wait_until

#: Every test user's password (argon2-hashed as any).
PASSWORD = "correct horse battery"
#: A simulated walk of 200 strides at 200 Hz (paced in real time: it runs for as long as a test needs).
SHORT: dict[str, Any] = {
    "kind": "simulated",
    "protocol": [{"speed_m_s": 1.2, "incline_deg": 0.0, "strides": 200}],
    "rate_hz": 200,
}


def auth_settings(tmp_path: Path, **kw: Any) -> Settings:
    """The app's settings with accounts on, on a fresh data folder under ``tmp_path`` (no demo, no leg view,
    1 MiB disk thresholds; ``TestClient``'s host allowed)."""
    return Settings(
        data_dir=tmp_path / "data", demo=False, leg_view=False, allowed_hosts=["testserver"], disk_warn_mb=1,
        disk_stop_mb=1, upload_min_free_mb=1, auth=True, **kw,
    )  # fmt: skip


def login(client: TestClient, name: str, password: str = PASSWORD) -> dict[str, str]:
    """Log ``name`` in; returns the headers a browser would send next (its cookie and CSRF token)."""
    client.cookies.clear()
    r = client.post("/api/auth/login", json={"name": name, "password": password})
    assert r.status_code == 200, r.text
    token = client.cookies.get(COOKIE)
    assert token
    client.cookies.clear()  # sent explicitly, per request, so that one client can act as several users
    return {"cookie": f"{COOKIE}={token}", CSRF_HEADER: r.json()["csrf_token"]}


def app_routes(routes: list[Any]) -> Iterator[Any]:
    """The app's routes, those of included routers too (FastAPI >= 0.16x wraps each included router)."""
    for route in routes:
        inner = getattr(route, "original_router", None)
        if inner is not None:
            yield from app_routes(inner.routes)
        else:
            yield route


def subject(client: TestClient, code: str = "P01") -> int:
    """A new subject's id."""
    r = client.post("/api/subjects", json={"code": code, "leg_length_m": 0.9, "mass_kg": 70.0})
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def session(client: TestClient, source: dict[str, Any] | None = None) -> dict[str, Any]:
    """A new subject's running session of ``source`` (default :data:`SHORT`)."""
    r = client.post("/api/sessions", json={"subject_id": subject(client), "source": source or SHORT})
    assert r.status_code == 201, r.text
    body: dict[str, Any] = r.json()
    return body


def wait_samples(client: TestClient, session_id: int, seconds: float = 1.0) -> None:
    """Wait until a live 200 Hz session has processed ``seconds`` of samples (its source paces in real time)."""
    runtime = client.app.state.ctx.manager.get(session_id)  # type: ignore[attr-defined]
    wait_until(lambda: runtime.samples >= 200 * seconds, 15.0, f"{200 * seconds:g} samples of session {session_id}")


def recorded(client: TestClient, sid: int, frames: list[SensorFrame]) -> tuple[int, SessionRuntime]:
    """A device session of subject ``sid`` driven through the real runtime; returns its trial id and runtime."""
    ctx = client.app.state.ctx  # type: ignore[attr-defined]
    r = client.post("/api/sessions", json={"subject_id": sid, "source": {"kind": "device"}, "start": False})
    assert r.status_code == 201, r.text
    session = ctx.store.get_session(r.json()["id"])
    model, _ = ctx.models.get("default")
    runtime = SessionRuntime(session, ctx.store.get_subject(sid), model, LiveDevice(), ctx.store, ctx.settings.data_dir)
    trial = runtime.start_recording("calibration")
    for frame in frames:
        runtime.process(frame, time.time_ns())
    runtime.stop_recording()
    return trial.id, runtime
