"""``/api/users``: accounts, for admins: list, add, change a role, disable, unlock, reset a password."""

from __future__ import annotations

from fastapi import APIRouter

from gaitscope.server.auth import Admin, allow
from gaitscope.server.routes.common import Ctx, audit
from gaitscope.sessions import schema

router = APIRouter(prefix="/api")


@router.get("/users", dependencies=[allow("admin")])
def list_users(c: Ctx) -> list[schema.User]:
    return c.accounts.list_users()


@router.post("/users", status_code=201)
def add_user(body: schema.UserCreate, c: Ctx, who: Admin) -> schema.User:
    """A new account (409 if the name is taken)."""
    audit(c, who, "user.add", body.name, after={"role": body.role})
    return c.accounts.add_user(body, by=who.name)


@router.patch("/users/{name}")
def change_user(name: str, body: schema.UserChange, c: Ctx, who: Admin) -> schema.User:
    """Change a role, disable or enable, unlock (forget its failed logins and the throttle's counts at its
    name), or reset the password; the account's logins end, and their open sockets close, when its role
    changes, it is disabled or its password reset. 409 for the last admin."""
    current = c.accounts.get_user(name)
    after = body.model_dump(exclude={"password"}, exclude_defaults=True)
    if body.password is not None:
        after["password"] = "reset"
    audit(c, who, "user.change", name, before={"role": current.role, "disabled": current.disabled}, after=after)
    return c.accounts.change_user(name, body, by=who.name)[1]
