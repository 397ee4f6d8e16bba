"""Failed logins on the real app (accounts on, real argon2): one answer for every refusal, whoever asks about
whichever name; a stranger's failures slow the stranger, never the admin at another address; one address
trying many names is slowed at every name; an admin's unlock clears it (issue 21, section 1)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from gaitscope.server.app import create_app
from gaitscope.sessions import schema
from gaitscope.sessions.accounts import LoginThrottle
from tests.server.apps import PASSWORD, auth_settings, login


class Clock:
    """The throttle's clock: still unless a test moves it (real argon2 takes a real 0.1 s a login)."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def app(tmp_path: Path) -> Iterator[TestClient]:
    with TestClient(create_app(auth_settings(tmp_path, lockout_after=3)), client=("10.0.0.1", 40000)) as c:
        accounts = c.app.state.ctx.accounts  # type: ignore[attr-defined]
        accounts.throttle = LoginThrottle(free=3, free_address=12, free_account=12, cap_s=900.0, clock=Clock())
        accounts.add_user(schema.UserCreate(name="ada", role="admin", password=PASSWORD), by="test")
        accounts.add_user(schema.UserCreate(name="cleo", role="clinician", password=PASSWORD), by="test")
        yield c


def _from(app: TestClient, address: str) -> TestClient:
    """A client at another address, on the same running app."""
    assert isinstance(app.app, FastAPI)
    return TestClient(app.app, client=(address, 40000))


def _answer(client: TestClient, name: str, password: str) -> tuple[int, bytes, list[tuple[str, str]]]:
    r = client.post("/api/auth/login", json={"name": name, "password": password})
    return r.status_code, r.content, _headers(r)


def _headers(r: Any) -> list[tuple[str, str]]:
    return sorted((k, v) for k, v in r.headers.items() if k != "date")


def test_every_refusal_is_the_same_answer(app: TestClient) -> None:
    guesser = _from(app, "10.0.0.66")
    unknown = _answer(guesser, "nobody", "not it at all")
    wrong = _answer(guesser, "cleo", "not it at all")
    assert unknown == wrong and unknown[:2] == (401, b'{"detail":"wrong name or password"}')
    for _ in range(3):
        _answer(guesser, "cleo", "not it at all")
        _answer(guesser, "nobody", "not it at all")
    held_back = _answer(guesser, "cleo", PASSWORD)  # the right password, held back after 3 failures
    held_back_unknown = _answer(guesser, "nobody", PASSWORD)
    assert held_back == held_back_unknown  # the lock is said, the same for a name that does not exist
    assert (
        held_back[:2]
        == (401, b'{"detail":"locked after too many failed logins: try again in 1 s (this attempt was not checked)"}')
        and ("retry-after", "1") in held_back[2]
    )
    assert app.app.state.ctx.accounts.throttle.wait("10.0.0.66", "cleo") > 0  # type: ignore[attr-defined]


def test_a_strangers_failures_never_stop_the_admin_at_another_address(app: TestClient) -> None:
    stranger = _from(app, "203.0.113.9")
    for i in range(8):  # the old lockout locked ada after 3 of these (lockout_after), for 15 minutes
        assert _answer(stranger, "ada", f"guess {i}")[0] == 401
    for i in range(12):  # and guesses from 12 more addresses: the name's count is over its free 12
        assert _answer(_from(app, f"198.51.100.{i}"), "ada", "guess")[0] == 401
    assert _answer(stranger, "ada", PASSWORD)[0] == 401  # the stranger, held back, does not get in
    admin = login(_from(app, "10.0.0.1"), "ada")  # the admin at her desk does, at the first attempt
    users = {u["name"]: u for u in app.get("/api/users", headers=admin).json()}
    assert users["ada"]["failed_logins"] == 0  # her good login started the count again
    assert _answer(stranger, "ada", PASSWORD)[0] == 401  # the stranger's own count did not


def test_one_address_trying_many_names_is_slowed_at_every_name(app: TestClient) -> None:
    sprayer = _from(app, "203.0.113.7")
    for i in range(12):  # lockout_after=3: the address waits after 4 x 3 failures, whatever the names
        assert _answer(sprayer, f"user{i}", "password1")[0] == 401
    assert _answer(sprayer, "cleo", PASSWORD)[0] == 401  # a name it never tried: held back
    assert login(_from(app, "10.0.0.2"), "cleo")  # from elsewhere, cleo logs in


def test_an_admins_unlock_clears_the_throttle(app: TestClient) -> None:
    desk = _from(app, "10.0.0.3")
    for _ in range(3):
        _answer(desk, "cleo", "a typo")
    assert _answer(desk, "cleo", PASSWORD)[0] == 401  # held back
    admin = login(app, "ada")
    users = {u["name"]: u for u in app.get("/api/users", headers=admin).json()}
    assert users["cleo"]["failed_logins"] == 3
    assert app.patch("/api/users/cleo", json={"unlock": True}, headers=admin).status_code == 200
    assert _answer(desk, "cleo", PASSWORD)[0] == 200
