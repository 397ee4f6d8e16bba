"""Accounts' password hashing and failed logins on a real SQLite file: no hash inside a transaction, at most
``hash_slots`` at once and never on the event loop; the same answer and the same work for every refusal; a
stranger's failures do not lock the owner out; an unlock clears the throttle, even one from another process."""

from __future__ import annotations

import asyncio
import contextlib
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from argon2 import PasswordHasher

from gaitscope.sessions import schema
from gaitscope.sessions.accounts import REFUSED, Accounts, LoginFailed, LoginThrottle
from gaitscope.sessions.store import Store

PASSWORD = "correct horse battery"


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


class WatchedStore(Store):
    """A store that knows which threads are inside one of its transactions."""

    def __init__(self, url: str) -> None:
        self.inside: set[int] = set()
        super().__init__(url)

    @contextlib.contextmanager
    def _watched(self, cm: Any) -> Iterator[Any]:
        with cm as s:
            self.inside.add(threading.get_ident())
            try:
                yield s
            finally:
                self.inside.discard(threading.get_ident())

    def reading(self) -> Any:
        return self._watched(super().reading())

    def writing(self) -> Any:
        return self._watched(super().writing())


class WatchedHasher(PasswordHasher):
    """A cheap argon2id that records, for each hash and verification, whether a transaction was open in its
    thread, which thread ran it, and how many ran at once."""

    def __init__(self, store: WatchedStore, seconds: float = 0.0) -> None:
        super().__init__(time_cost=1, memory_cost=8, parallelism=1)
        self.store, self.seconds = store, seconds
        self.calls: list[tuple[str, bool, int]] = []
        self.running = self.most = 0
        self._lock = threading.Lock()

    def _call(self, kind: str, fn: Any, *args: Any) -> Any:
        with self._lock:
            self.calls.append((kind, threading.get_ident() in self.store.inside, threading.get_ident()))
            self.running += 1
            self.most = max(self.most, self.running)
        try:
            time.sleep(self.seconds)  # the real hash's time, without its CPU
            return fn(*args)
        finally:
            with self._lock:
                self.running -= 1

    def hash(self, password: str | bytes, *, salt: bytes | None = None) -> str:
        return str(self._call("hash", super().hash, password))

    def verify(self, hash: str | bytes, password: str | bytes) -> Any:
        return self._call("verify", super().verify, hash, password)


@pytest.fixture
def parts(tmp_path: Path) -> tuple[Accounts, WatchedHasher, Clock]:
    store = WatchedStore(f"sqlite:///{tmp_path / 'db.sqlite'}")
    hasher = WatchedHasher(store)
    clock = Clock()
    throttle = LoginThrottle(free=3, free_address=12, free_account=12, clock=clock)
    accounts = Accounts(store, hasher=hasher, throttle=throttle)
    accounts.add_user(schema.UserCreate(name="ada", role="admin", password=PASSWORD), by="test")
    return accounts, hasher, clock


def _refusal(accounts: Accounts, name: str, password: str, address: str) -> str:
    with pytest.raises(LoginFailed) as e:
        accounts.login(name, password, address)
    return str(e.value)


def test_no_hash_runs_inside_a_transaction(parts: tuple[Accounts, WatchedHasher, Clock]) -> None:
    accounts, hasher, _ = parts
    accounts.login("ada", PASSWORD, "a")
    _refusal(accounts, "ada", "wrong", "a")
    _refusal(accounts, "nobody", "wrong", "a")
    accounts.change_user("ada", schema.UserChange(password="a new password 1"), by="test")
    accounts.change_password("ada", "a new password 1", "a new password 2")
    accounts.add_user(schema.UserCreate(name="eve", role="viewer", password=PASSWORD), by="test")
    kinds = [k for k, _, _ in hasher.calls]
    assert kinds.count("hash") >= 5 and kinds.count("verify") == 4  # add x2, the dummy, reset, change
    assert not [c for c in hasher.calls if c[1]], "a hash ran inside a database transaction"


def test_every_refusal_is_the_same_answer_after_one_verification(parts: tuple[Accounts, WatchedHasher, Clock]) -> None:
    accounts, hasher, _ = parts
    with pytest.raises(LoginFailed):  # the dummy hash is made at the first unknown name: not counted below
        accounts.login("nobody", "x", "warm")
    answers = []
    for name, password in [("nobody", PASSWORD), ("ada", "wrong")] * 4 + [("ada", PASSWORD), ("nobody", PASSWORD)]:
        before = len(hasher.calls)
        answers.append(_refusal(accounts, name, password, "guesser"))
        assert [k for k, _, _ in hasher.calls[before:]] == ["verify"]  # held back or not, known or not
    # a known and an unknown name get the same answer at every step: the tries left as they run low, the lock
    # their third failure starts (free=3), then held back, the right password too
    assert answers[0::2][:4] == answers[1::2][:4] and answers[8] == answers[9]
    locked = f"{REFUSED}. Too many failed logins: logins with this name from this computer are locked for 1 s"
    held = "locked after too many failed logins: try again in 1 s (this attempt was not checked)"
    assert [a.split(" (each")[0] for a in answers[::2]] == [
        REFUSED,
        f"{REFUSED} (1 try left before logins with this name are locked)",
        locked,
        held,
        held,
    ]


def test_a_strangers_failures_never_stop_the_owner_from_another_address(
    parts: tuple[Accounts, WatchedHasher, Clock],
) -> None:
    accounts, _, _ = parts
    for i in range(40):  # many guesses from one address, and one from each of 20 others
        _refusal(accounts, "ada", f"guess {i}", "stranger")
    for i in range(20):
        _refusal(accounts, "ada", "guess", f"10.0.0.{i}")
    user = accounts.get_user("ada")
    assert user.failed_logins == 23  # the stranger's 3 (then held back: not checked, not counted) + 20
    assert accounts.throttle.wait("10.0.0.5", "ada") > 0  # the addresses that guessed wait for the name's count
    assert accounts.login("ada", PASSWORD, "the-admins-desk").user.name == "ada"
    assert accounts.get_user("ada").failed_logins == 0


def test_an_unlock_clears_the_throttle_even_from_another_process(
    parts: tuple[Accounts, WatchedHasher, Clock], tmp_path: Path
) -> None:
    accounts, _, clock = parts
    for i in range(12):
        _refusal(accounts, "ada", f"guess {i}", f"10.0.0.{i}")
    assert accounts.throttle.name_wait("ada") == 1.0
    assert accounts.get_user("ada").locked_until_utc is not None  # what the admins see
    # the command line's unlock: another Accounts on the same database (as `gaitscope user unlock`)
    other = Accounts(Store(f"sqlite:///{tmp_path / 'db.sqlite'}"))
    other.change_user("ada", schema.UserChange(unlock=True), by="cli")
    assert accounts.login("ada", PASSWORD, "10.0.0.3").user.name == "ada"  # a guessing address, let in again
    for _ in range(3):
        _refusal(accounts, "ada", "typo", "desk")
    assert accounts.throttle.wait("desk", "ada") == 1.0
    accounts.change_user("ada", schema.UserChange(unlock=True), by="admin")  # this process: the pairs too
    assert accounts.throttle.wait("desk", "ada") == 0.0
    clock.t += 1.0
    assert accounts.throttle.wait("10.0.0.4", "ada") == 0.0


def test_login_async_hashes_off_the_loop_at_most_two_at_once(tmp_path: Path) -> None:
    store = WatchedStore(f"sqlite:///{tmp_path / 'db.sqlite'}")
    hasher = WatchedHasher(store, seconds=0.05)
    accounts = Accounts(store, hasher=hasher, hash_slots=2)
    accounts.add_user(schema.UserCreate(name="ada", role="admin", password=PASSWORD), by="test")
    hasher.calls.clear()
    hasher.most = 0

    async def flood() -> tuple[int, float]:
        loop_thread = threading.get_ident()
        beats = 0

        async def heartbeat() -> None:
            nonlocal beats
            while True:
                await asyncio.sleep(0.01)
                beats += 1

        beat = asyncio.create_task(heartbeat())
        t0 = time.perf_counter()
        results = await asyncio.gather(
            *(accounts.login_async(f"user{i}", "guess", f"10.0.1.{i}") for i in range(16)), return_exceptions=True
        )
        elapsed = time.perf_counter() - t0
        beat.cancel()
        assert all(isinstance(r, LoginFailed) for r in results)
        assert all(thread != loop_thread for _, _, thread in hasher.calls)
        return beats, elapsed

    beats, elapsed = asyncio.run(flood())
    assert hasher.most <= 2  # 17 hashes (the dummy's and 16 verifications), at most two at once
    assert elapsed >= 16 * 0.05 / 2 * 0.9
    assert beats >= elapsed / 0.01 * 0.5  # the loop kept running meanwhile
