"""Who is asking, and may they: identities, roles, the per-route guard, CSRF, device tokens.

Every route declares its rule with one of three dependencies, and a test (``tests/server/test_roles.py``)
walks the OpenAPI document and the app's websocket routes to check that none is left without one:

- ``allow(permission)``: a logged-in user whose role holds ``permission`` (:data:`PERMISSIONS`); the
  dependency's value is the caller's :class:`Who`. 401 without a login, 403 for a role without the
  permission, and 403 for a state-changing request without the login's CSRF token;
- ``public()``: anyone (the health check, the login itself);
- ``device()``: a device with its session's token (``/ws/devices/{id}``).

With accounts off (``Settings.auth``, the default on loopback), nobody logs in: every caller is ``local``,
with the admin's permissions, which is what "anyone who can reach 127.0.0.1" amounts to. The server says so
at start-up; it refuses to listen anywhere but loopback like that. Device tokens are required either way:
a stray program cannot push frames into a session that drives a motor.

CSRF: the login cookie is ``SameSite=Strict`` and ``HttpOnly``, the origin rule (:mod:`gaitscope.server.origin`)
refuses foreign origins, and each login has a CSRF token the browser sends back in ``X-CSRF-Token`` with
every request that is not GET, HEAD or OPTIONS (OWASP's synchronizer token). Websockets cannot carry the
header; the origin rule covers them.
"""

from __future__ import annotations

import hmac
from dataclasses import dataclass
from typing import TYPE_CHECKING, Annotated, Any, Final, get_args

from fastapi import Depends, HTTPException, WebSocketException, status
from starlette.requests import HTTPConnection

from gaitscope.server.origin import SAFE_METHODS
from gaitscope.sessions import schema

if TYPE_CHECKING:
    from gaitscope.server.app import AppContext

__all__ = [
    "COOKIE",
    "CSRF_HEADER",
    "LOCAL",
    "PERMISSIONS",
    "Admin",
    "Annotator",
    "Assistant",
    "LimitSetter",
    "LoggedIn",
    "Promoter",
    "Reader",
    "Runner",
    "Uploader",
    "Who",
    "allow",
    "device",
    "device_token",
    "public",
    "who_of",
]

COOKIE: Final = "gaitscope_login"
CSRF_HEADER: Final = "X-CSRF-Token"
ALL_PERMISSIONS: Final[frozenset[schema.Permission]] = frozenset(get_args(schema.Permission))

#: Which role may do what (issue #13): the admin everything; the clinician runs sessions, changes assistance,
#: promotes personalized models and sets the experimenters' limits; the experimenter runs sessions and trials,
#: annotates, uploads and re-runs, and changes assistance within those limits; the viewer reads.
PERMISSIONS: Final[dict[schema.Role, frozenset[schema.Permission]]] = {
    "admin": ALL_PERMISSIONS,
    "clinician": frozenset(
        {"read", "run", "annotate", "upload", "assist", "assist_within_limits", "promote", "set_limits"}
    ),
    "experimenter": frozenset({"read", "run", "annotate", "upload", "assist_within_limits"}),
    "viewer": frozenset({"read"}),
}
#: What each permission lets one do, in words (for the 403's message).
DOES: Final[dict[schema.Permission, str]] = {
    "read": "see data",
    "run": "run sessions and trials",
    "annotate": "annotate",
    "upload": "upload recordings",
    "assist": "change assistance",
    "assist_within_limits": "change assistance within the clinician's limits",
    "promote": "promote or roll back personalized models",
    "set_limits": "set the experimenters' assistance limits",
    "admin": "administer users, models and the audit trail",
}


@dataclass(frozen=True)
class Who:
    """The caller: a user's name and role, with their login (None: accounts are off, the caller is local)."""

    name: str
    role: schema.Role
    login_id: int | None = None
    csrf_token: str | None = None

    def may(self, permission: schema.Permission) -> bool:
        return permission in PERMISSIONS[self.role]

    @property
    def permissions(self) -> list[schema.Permission]:
        return sorted(PERMISSIONS[self.role])


#: The caller when accounts are off.
LOCAL: Final = Who(name="local", role="admin")


def _ctx(conn: HTTPConnection) -> AppContext:
    return conn.app.state.ctx


def _refuse(conn: HTTPConnection, code: int, detail: str) -> Exception:
    """The refusal for this kind of connection: an HTTP error, or a websocket closed with 1008 (before accept)."""
    if conn.scope["type"] == "websocket":
        return WebSocketException(code=status.WS_1008_POLICY_VIOLATION, reason=detail[:120])
    headers = {"WWW-Authenticate": 'Cookie realm="gaitscope"'} if code == 401 else None
    return HTTPException(code, detail, headers=headers)


def who_of(conn: HTTPConnection) -> Who | None:
    """The caller, from the login cookie; :data:`LOCAL` with accounts off; None if nobody is logged in."""
    c = _ctx(conn)
    if not c.settings.auth:
        return LOCAL
    cached = conn.scope.get("gaitscope.who")
    if isinstance(cached, Who):
        return cached
    token = conn.cookies.get(COOKIE)
    login = c.accounts.identify(token) if token else None
    if login is None:
        return None
    who = Who(name=login.user.name, role=login.user.role, login_id=login.login_id, csrf_token=login.csrf_token)
    conn.scope["gaitscope.who"] = who  # the audit middleware reads it
    return who


class _Guard:
    """The dependency behind :func:`allow`; ``permission`` None: any logged-in user."""

    def __init__(self, permission: schema.Permission | None) -> None:
        self.permission = permission

    def __call__(self, conn: HTTPConnection) -> Who:
        who = who_of(conn)
        if who is None:
            raise _refuse(conn, 401, "log in first")
        if self.permission is not None and not who.may(self.permission):
            raise _refuse(conn, 403, f"{who.role} {who.name!r} may not {DOES[self.permission]}")
        if conn.scope["type"] == "http" and conn.scope["method"] not in SAFE_METHODS and who.login_id is not None:
            sent = conn.headers.get(CSRF_HEADER, "")
            if not (who.csrf_token and hmac.compare_digest(sent.encode(), who.csrf_token.encode())):
                raise _refuse(conn, 403, f"missing or wrong {CSRF_HEADER} header: reload the page")
        return who


def allow(permission: schema.Permission | None) -> Any:
    """The route's rule: a logged-in user holding ``permission`` (None: any logged-in user). Use as a
    parameter's default (``who: Who = allow("run")``) or in ``dependencies=[...]``."""
    return Depends(_Guard(permission))


def _public() -> None:
    """Anyone may: the route serves no data and changes nothing of anyone's (health, login)."""


def public() -> Any:
    return Depends(_public)


def device_token(conn: HTTPConnection) -> str | None:
    """The token a device sent: ``Authorization: Bearer <token>``, or the ``token`` query parameter (for
    devices whose websocket library cannot set headers)."""
    auth = conn.headers.get("authorization", "")
    if auth[:7].lower() == "bearer ":
        return auth[7:].strip() or None
    return conn.query_params.get("token") or None


def _device(conn: HTTPConnection) -> int:
    raw = str(conn.path_params["session_id"])
    session_id = int(raw) if raw.isascii() and raw.isdigit() and len(raw) <= 19 else 0
    if not 0 < session_id <= schema.INT64_MAX:
        raise _refuse(conn, 404, f"no session {raw[:40]!r}: a session id is a whole number from 1 to 2**63-1")
    token = device_token(conn)
    if token is None:
        raise _refuse(conn, 401, f"session {session_id}: no device token (issue one for this session)")
    token_id = _ctx(conn).accounts.device_token_id(session_id, token)
    if token_id is None:
        raise _refuse(conn, 403, f"session {session_id}: wrong or revoked device token")
    return token_id


def device() -> Any:
    """The rule of a device's websocket: a valid token of the session in the path; its value is the token's id."""
    return Depends(_device)


#: Route parameters for the caller, each with its rule (``who: Runner``).
LoggedIn = Annotated[Who, allow(None)]
Reader = Annotated[Who, allow("read")]
Runner = Annotated[Who, allow("run")]
Annotator = Annotated[Who, allow("annotate")]
Uploader = Annotated[Who, allow("upload")]
Assistant = Annotated[Who, allow("assist_within_limits")]
Promoter = Annotated[Who, allow("promote")]
LimitSetter = Annotated[Who, allow("set_limits")]
Admin = Annotated[Who, allow("admin")]
