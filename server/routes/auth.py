"""``/api/auth``: log in and out, who am I, change my password.

A login sets the ``gaitscope_login`` cookie (HttpOnly, SameSite=Strict, Secure behind TLS, for the login's
length) and answers with :class:`~gaitscope.sessions.schema.Me`, whose ``csrf_token`` the browser sends back in the
``X-CSRF-Token`` header with every state-changing request. With accounts off there is no login:
``GET /api/auth/me`` answers ``local``, and ``POST /api/auth/login`` says so (409).

Failed logins are throttled per client address and per name (:mod:`gaitscope.sessions.accounts.throttle`); every
refusal is the same 401 (:data:`~gaitscope.sessions.accounts.REFUSED`) after the same work, whether the name exists
or not: as the tries before a wait run low it says how many are left, and once the address must wait it says so
and for how long (also as ``Retry-After``, in seconds). The client's address is the
connection's, or behind a TLS proxy (``Settings.behind_tls_proxy``) the one uvicorn takes from the proxy's
``X-Forwarded-For``. Password hashing runs off the event loop, outside any database transaction, in a pool
of its own (:meth:`~gaitscope.sessions.accounts.Accounts.login_async`).
"""

from __future__ import annotations

import functools
import math

import anyio.to_thread
from fastapi import APIRouter, HTTPException, Request, Response

from gaitscope.server.auth import COOKIE, LoggedIn, Who, public
from gaitscope.server.routes.common import Ctx, audit
from gaitscope.sessions import schema
from gaitscope.sessions.accounts import LoginFailed

router = APIRouter(prefix="/api/auth")


def _me(c: Ctx, who: Who) -> schema.Me:
    return schema.Me(
        name=who.name, role=who.role, accounts=c.settings.auth, permissions=who.permissions, csrf_token=who.csrf_token
    )


@router.post("/login", dependencies=[public()])
async def login(body: schema.LoginRequest, request: Request, response: Response, c: Ctx) -> schema.Me:
    """Check the name and password; 401 with one answer for an unknown name and a wrong password (with the
    tries left as they run low, the wait once one starts), another for an attempt the throttle holds back; every
    failure audited and counted by the throttle. A disabled account's right password is told so."""
    if not c.settings.auth:
        raise HTTPException(409, "accounts are off on this server: there is nothing to log in to")
    client = request.client.host if request.client else "unknown"
    try:
        done = await c.accounts.login_async(body.name, body.password, client)
    except LoginFailed as e:
        record = functools.partial(
            c.audit.record, user=body.name, role="none", action="login.failed", target=client, outcome="refused",
            detail=e.detail,
        )  # fmt: skip
        await anyio.to_thread.run_sync(record)
        request.scope["gaitscope.audited"] = True  # recorded here: the audit middleware need not
        wait = {"Retry-After": str(math.ceil(e.retry_after_s))} if e.retry_after_s > 0 else None
        raise HTTPException(401, str(e), headers=wait) from None
    who = Who(done.user.name, done.user.role, done.login_id, done.csrf_token)
    await anyio.to_thread.run_sync(audit, c, who, "login", client)
    assert done.token is not None
    response.set_cookie(
        COOKIE, done.token, max_age=int(c.accounts.login_length.total_seconds()), httponly=True, samesite="strict",
        secure=c.settings.tls, path="/",
    )  # fmt: skip
    return _me(c, who)


@router.post("/logout", status_code=204)
def logout(response: Response, c: Ctx, who: LoggedIn) -> Response:
    if who.login_id is not None:
        audit(c, who, "logout", who.name)
        c.accounts.logout(who.login_id)
    response.status_code = 204
    response.delete_cookie(COOKIE, path="/", httponly=True, samesite="strict", secure=c.settings.tls)
    return response


@router.get("/me")
def me(c: Ctx, who: LoggedIn) -> schema.Me:
    """Who the server takes the caller to be: 401 when accounts are on and nobody is logged in."""
    return _me(c, who)


@router.post("/password", status_code=204)
def change_password(body: schema.PasswordChange, request: Request, c: Ctx, who: LoggedIn) -> Response:
    """Change one's own password (the current one checked; a wrong one counts as a failed login from this
    address); every login of the account ends, this one too, and their open streams close. A sync route: the
    hashes run in a worker thread, outside any transaction."""
    if who.login_id is None:
        raise HTTPException(409, "accounts are off on this server: there is no password to change")
    audit(c, who, "password.change", who.name)
    client = request.client.host if request.client else "unknown"
    try:
        c.accounts.change_password(who.name, body.current, body.new, client)
    except LoginFailed as e:
        raise HTTPException(403, str(e)) from None
    response = Response(status_code=204)
    response.delete_cookie(COOKIE, path="/", httponly=True, samesite="strict", secure=c.settings.tls)
    return response
