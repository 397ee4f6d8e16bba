"""Accounts for the e2e suite (issue #13): every e2e server runs with accounts on, with one user per role.

The users are made before the server starts, the way an operator makes the first admin
(``gaitscope user --data-dir D add --role R NAME --password-stdin``); each is named after its role
(``admin``, ``clinician``, ``experimenter``, ``viewer``), so an event "by clinician" is the clinician's.

Outside the browser, :func:`client` logs in once per server and user and sends the login cookie and the
CSRF header with every request, as the dashboard does. In the browser, :func:`log_in` logs a page's context
in through the API (the cookie lands in the context); one test (``test_accounts.py``) goes through the login
page by typing instead.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
import urllib.error
import urllib.request
from dataclasses import dataclass, field
from http.cookies import SimpleCookie
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from tests import load

if TYPE_CHECKING:
    from playwright.sync_api import BrowserContext

ROLES: Final = ("admin", "clinician", "experimenter", "viewer")
#: The users' passwords (at least 10 characters, the server's rule).
PASSWORDS: Final = {name: f"{name}-e2e-password" for name in ROLES}
#: The environment of every e2e server: accounts on (loopback, so no TLS needed).
AUTH_ENV: Final = {**os.environ, "GAITSCOPE_AUTH": "true"}
COOKIE: Final = "gaitscope_login"


def gaitscope(*args: str, stdin: str | None = None) -> subprocess.CompletedProcess[str]:
    """Runs ``gaitscope ARGS`` (this venv's) with accounts on; fails the caller with its output if it fails."""
    exe = str(Path(sys.executable).with_name("gaitscope"))
    done = subprocess.run([exe, *args], input=stdin, capture_output=True, text=True, env=AUTH_ENV, timeout=120)
    if done.returncode != 0:
        raise AssertionError(f"gaitscope {' '.join(args)} exited with {done.returncode}:\n{done.stdout}{done.stderr}")
    return done


def add_users(data_dir: Path | str, names: tuple[str, ...] = ROLES) -> None:
    """One user per role (named after it) in the database of ``data_dir``, before the server starts."""
    for name in names:
        gaitscope("user", "--data-dir", str(data_dir), "add", "--role", name, name, "--password-stdin",
                  stdin=PASSWORDS[name] + "\n")  # fmt: skip


class Refused(AssertionError):
    """The server refused a request: its status and its ``detail``."""

    def __init__(self, method: str, path: str, status: int, detail: Any):
        super().__init__(f"{method} {path}: {status} {detail}")
        self.status = status
        self.detail = detail


@dataclass
class Client:
    """A logged-in user outside the browser: the login cookie and the CSRF token of one login."""

    base: str
    name: str
    cookie: str = ""
    csrf: str = ""
    me: dict[str, Any] = field(default_factory=dict)

    def log_in(self, password: str | None = None) -> dict[str, Any]:
        body = json.dumps({"name": self.name, "password": password or PASSWORDS[self.name]}).encode()
        req = urllib.request.Request(
            f"{self.base}/api/auth/login", data=body, method="POST", headers={"Content-Type": "application/json"}
        )
        try:
            with urllib.request.urlopen(req, timeout=30) as resp:
                jar = SimpleCookie()
                for header in resp.headers.get_all("Set-Cookie") or []:
                    jar.load(header)
                self.me = json.loads(resp.read())
        except urllib.error.HTTPError as e:
            raise Refused("POST", "/api/auth/login", e.code, _detail(e)) from None
        assert COOKIE in jar, f"the login set no {COOKIE} cookie"
        self.cookie = jar[COOKIE].value
        self.csrf = str(self.me["csrf_token"])
        return self.me

    def raw(self, method: str, path: str, body: Any = None, headers: dict[str, str] | None = None) -> bytes:
        """The answer's bytes; :class:`Refused` for an error status. A 401 (the login ended, e.g. a server
        restart with a fresh database) logs in again once."""
        for attempt in (0, 1):
            if not self.cookie:
                self.log_in()
            data = None if body is None else (body if isinstance(body, bytes) else json.dumps(body).encode())
            h = {"Content-Type": "application/json", "Cookie": f"{COOKIE}={self.cookie}", **(headers or {})}
            if method not in ("GET", "HEAD", "OPTIONS"):
                h["X-CSRF-Token"] = self.csrf
            req = urllib.request.Request(self.base + path, data=data, method=method, headers=h)
            try:
                with urllib.request.urlopen(req, timeout=30) as resp:
                    return bytes(resp.read())
            except urllib.error.HTTPError as e:
                if e.code == 401 and attempt == 0:
                    self.cookie = ""
                    continue
                raise Refused(method, path, e.code, _detail(e)) from None
        raise AssertionError("unreachable")

    def call(self, method: str, path: str, body: Any = None) -> Any:
        """A REST call as this user: the JSON answer (None for an empty one)."""
        return json.loads(self.raw(method, path, body) or b"null")


def _detail(e: urllib.error.HTTPError) -> Any:
    text = e.read().decode(errors="replace")
    try:
        return json.loads(text).get("detail", text)
    except (ValueError, AttributeError):
        return text


_clients: dict[tuple[str, str], Client] = {}


def client(base: str, name: str = "clinician") -> Client:
    """The user ``name`` logged in to the server at ``base`` (once per server and user)."""
    key = (base, name)
    if key not in _clients:
        _clients[key] = Client(base, name)
    return _clients[key]


def log_in(context: BrowserContext, base: str, name: str = "clinician") -> dict[str, Any]:
    """Logs a browser context in as ``name`` through the API: the cookie lands in the context, and the pages
    opened after load ``me`` with it (and its CSRF token). Returns the ``Me``.

    Sent again once if the connection was reset: the request context reuses an idle connection, and one the
    server closed at its keep-alive timeout (5 s) just as the login went out is reset (seen on a loaded
    machine); a browser retries such a request itself, Playwright's request context does not."""
    from playwright.sync_api import Error

    data = {"name": name, "password": PASSWORDS[name]}
    try:
        resp = context.request.post(f"{base}/api/auth/login", data=data)
    except Error as e:
        if "ECONNRESET" not in str(e):
            raise
        resp = context.request.post(f"{base}/api/auth/login", data=data)
    assert resp.ok, f"login of {name} refused: {resp.status} {resp.text()}"
    me: dict[str, Any] = resp.json()
    return me


def call(base: str, method: str, path: str, body: dict[str, Any] | None = None, user: str = "clinician") -> Any:
    """A REST call from outside the browser (another screen, logged in as ``user``); the JSON answer."""
    return client(base, user).call(method, path, body)


def simulated_session(
    base: str, code: str, speed_m_s: float = 1.2, incline_deg: float = 0.0, strides: int = 300, **settings: Any
) -> tuple[dict[str, Any], dict[str, Any]]:
    """A new subject ``code`` (0.9 m, 70 kg) and a running simulated session of it at 100 Hz walking one
    protocol step (``settings``: the session's, if any): ``(subject, session)`` as the API answered them."""
    subject = call(base, "POST", "/api/subjects", {"code": code, "leg_length_m": 0.9, "mass_kg": 70.0})
    step = {"speed_m_s": speed_m_s, "incline_deg": incline_deg, "strides": strides}
    body: dict[str, Any] = {
        "subject_id": subject["id"],
        "source": {"kind": "simulated", "rate_hz": 100.0, "protocol": [step]},
    }
    if settings:
        body["settings"] = settings
    return subject, call(base, "POST", "/api/sessions", body)


def session_time(base: str, session_id: int, at_least: float = -math.inf) -> float:
    """The running session's time (s), once it has reached ``at_least``: :func:`tests.load.session_time` as
    the clinician."""
    c = client(base)
    if not c.cookie:
        c.log_in()
    return load.session_time(base, session_id, at_least, {"Cookie": f"{COOKIE}={c.cookie}"})


def record(base: str, session_id: int, seconds: float, name: str) -> dict[str, Any]:
    """A recording named ``name`` of the running session's next ``seconds`` (the session streams in real
    time: the wait is the walk being recorded, as long as a clinician would let it run); the finished trial."""
    call(base, "POST", f"/api/sessions/{session_id}/recording", {"action": "start", "name": name})
    time.sleep(seconds)
    trial: dict[str, Any] = call(base, "POST", f"/api/sessions/{session_id}/recording", {"action": "stop"})
    assert trial["status"] == "finished", trial
    return trial
