"""Accounts: users with argon2id password hashes, login sessions with a failed-login throttle, device tokens,
and the assistance limits a clinician sets for experimenters.

One :class:`Accounts` per server, over the :class:`~gaitscope.sessions.store.Store`'s database (its tables are
:mod:`sessions.accounts.tables`). Every method is one transaction, but a login and a password change: a read, the
hash outside any transaction, then a write. Times are ISO-8601 UTC.

Choices:

- Passwords: argon2id through argon2-cffi's :class:`~argon2.PasswordHasher` with its defaults (RFC 9106's
  second recommended profile, 64 MiB, 3 passes), rehashed on the next login when those defaults change.
- Failed logins are throttled, not locked out (:mod:`gaitscope.sessions.accounts.throttle`): per (address, name),
  per address and per name, with exponential waits up to ``lockout_minutes``; a stranger's failures never
  stop the owner logging in from an address that has not failed. Every refusal is the same answer
  (:data:`REFUSED`) after the same work, one argon2 verification, whether the name exists or not or the
  password is wrong (an unknown name is verified against a fixed dummy hash); as the tries before a wait run
  low it says how many are left, and a failure that starts a wait, and an attempt held back by one, say so
  and for how long (:func:`_refusal`: from the throttle's counts, which never look at whether the name exists).
  The database keeps the account's failed logins in a row and until when failing addresses wait (what the
  admins see); an admin's unlock clears both.
- Hashing never runs inside a database transaction: a login reads the account, verifies outside any
  transaction, then writes; at most ``hash_slots`` hashes run at once in the process (one by default: each
  takes 64 MiB, and its 4 lanes about 0.12 s of both cores of a 2-core machine), and
  :meth:`Accounts.login_async` runs them in threads of their own, never on the event loop nor in the
  threads the other routes share.
- Login sessions: a 256-bit random token in the cookie, stored as its SHA-256; each has its own CSRF token
  (the synchronizer-token pattern, OWASP) and ends ``login_hours`` after it began (a clinic's day), or at
  logout, or when the password changes (every login of the user ends). The sockets opened with a login
  are told when it ends (:class:`~gaitscope.sessions.accounts.watch.LoginWatch`, :attr:`Accounts.watch`).
- Device tokens: 256-bit random, one session each, shown once, stored as SHA-256, revocable.
"""

from __future__ import annotations

import datetime as dt
import functools
import hashlib
import hmac
import math
import secrets
import threading
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Final

import anyio.to_thread
from anyio import CapacityLimiter
from argon2 import PasswordHasher
from argon2.exceptions import InvalidHashError, VerificationError, VerifyMismatchError
from sqlalchemy import func, orm, select, update

from gaitscope.sessions import schema
from gaitscope.sessions.accounts.tables import DeviceTokenRow, LimitsRow, LoginRow, UserRow
from gaitscope.sessions.accounts.throttle import LoginThrottle
from gaitscope.sessions.accounts.watch import LoginWatch
from gaitscope.sessions.store import Conflict, NotFound, Store

__all__ = ["REFUSED", "Accounts", "Login", "LoginFailed"]

#: A fixed hash verified for unknown names, so that they take as long as known ones.
_DUMMY_PASSWORD = "not a password of anyone's"

#: The one answer to every refused login: an unknown name, a wrong password, or an attempt the throttle held back
#: (OWASP: one generic message whether the name is wrong, the password, or the account is locked).
REFUSED: Final = "wrong name or password"


class LoginFailed(PermissionError):
    """A login was refused; the message says why in words fit to show (a login's refusal is always
    :data:`REFUSED`, except a disabled account's with the right password), ``detail`` what happened, for the
    audit trail."""

    def __init__(self, message: str, detail: str | None = None, retry_after_s: float = 0.0) -> None:
        super().__init__(message)
        self.detail = detail or message
        self.retry_after_s = retry_after_s  # > 0: the throttle holds this address's next attempt back so long


@dataclass(frozen=True)
class _Attempt:
    """A login attempt between its read of the account and its verification."""

    name: str
    address: str
    user_id: int | None  # None: no such name
    password_hash: str | None  # None: no such name (the dummy hash is verified)
    waits: bool  # the throttle holds this attempt back: refused whatever the password


@dataclass(frozen=True)
class Login:
    """A logged-in user and their login session's tokens (the cookie's ``token`` only when just created)."""

    user: schema.User
    login_id: int
    csrf_token: str
    token: str | None = None


def _now() -> dt.datetime:
    return dt.datetime.now(dt.UTC)


def _stamp(t: dt.datetime) -> str:
    return t.isoformat(timespec="seconds")


def _seconds(wait: float) -> str:
    """A wait in words, rounded up: "1 s", "64 s", "4 min 16 s"."""
    s = math.ceil(wait)
    return f"{s} s" if s < 120 else f"{s // 60} min" + (f" {s % 60} s" if s % 60 else "")


def _refusal(wait: float, left: int, free: int) -> str:
    """A wrong name or password in words: :data:`REFUSED`, with the tries left before this address waits once
    they run low (at most 2, and fewer than ``free`` - 1: a first typo is not warned of), or the wait the
    failure started. The counts are the throttle's, the same for a name that does not exist."""
    if wait > 0:
        return (
            f"{REFUSED}. Too many failed logins: logins with this name from this computer are locked for "
            f"{_seconds(wait)} (each further failure doubles the wait)"
        )
    if left <= min(2, free - 2):
        return f"{REFUSED} ({left} {'try' if left == 1 else 'tries'} left before logins with this name are locked)"
    return REFUSED


def _held_back(wait: float) -> str:
    """An attempt the throttle held back (not checked) in words."""
    again = _seconds(max(wait, 0.5))
    return f"locked after too many failed logins: try again in {again} (this attempt was not checked)"


def _sha256(token: str) -> str:
    return hashlib.sha256(token.encode()).hexdigest()


def _user(row: UserRow) -> schema.User:
    return schema.User.model_validate(row, from_attributes=True)


def _device_token(row: DeviceTokenRow, token: str | None = None) -> schema.DeviceToken:
    return schema.DeviceToken.model_validate(
        {**{f: getattr(row, f) for f in schema.DeviceToken.model_fields if f != "token"}, "token": token}
    )


class Accounts:
    """Users, logins, device tokens and assistance limits in ``store``'s database.

    Args:
        store: the database.
        lockout_after: failed logins of one address at one name before its attempts wait (1 s, doubling
            with each further failure); see :class:`~gaitscope.sessions.accounts.throttle.LoginThrottle` for the
            counts per address and per name, which start at four times this.
        lockout_minutes: the longest wait.
        login_hours: how long a login session lasts.
        hasher: the password hasher (argon2-cffi's defaults unless given; tests may pass a cheaper one).
        throttle: the failed-login throttle (made from ``lockout_after`` and ``lockout_minutes`` unless given).
        hash_slots: argon2 hashes or verifications running at once in this process, at most (argon2-cffi's
            4 lanes make one use every core of a small machine; more slots take the cores from the sessions).
    """

    def __init__(
        self,
        store: Store,
        *,
        lockout_after: int = 5,
        lockout_minutes: float = 15.0,
        login_hours: float = 12.0,
        hasher: PasswordHasher | None = None,
        throttle: LoginThrottle | None = None,
        hash_slots: int = 1,
    ) -> None:
        if lockout_after < 1 or lockout_minutes <= 0 or login_hours <= 0 or hash_slots < 1:
            raise ValueError("lockout_after, lockout_minutes, login_hours and hash_slots must be positive")
        self._store = store
        self.login_length = dt.timedelta(hours=login_hours)
        self._hasher = hasher or PasswordHasher()
        self.throttle = throttle or LoginThrottle(
            free=lockout_after, free_address=4 * lockout_after, free_account=4 * lockout_after,
            cap_s=60.0 * lockout_minutes,
        )  # fmt: skip
        self.watch = LoginWatch()
        self._hash_slots = threading.BoundedSemaphore(hash_slots)
        self._hash_slot_count = hash_slots
        self._pools: tuple[CapacityLimiter, CapacityLimiter] | None = None

    @functools.cached_property
    def _dummy_hash(self) -> str:
        """The hash an unknown name's password is checked against: made at the first such login, not with every
        :class:`Accounts` (an argon2 hash costs 64 MiB and tens of milliseconds)."""
        return self._hash(_DUMMY_PASSWORD)

    def _hash(self, password: str) -> str:
        with self._hash_slots:
            return self._hasher.hash(password)

    def _verify(self, password_hash: str, password: str) -> bool:
        with self._hash_slots:
            try:
                return self._hasher.verify(password_hash, password)
            except (VerifyMismatchError, VerificationError, InvalidHashError):
                return False

    # --- users --------------------------------------------------------------------------------------

    def count_users(self) -> int:
        with self._store.reading() as s:
            return int(s.scalar(select(func.count()).select_from(UserRow)) or 0)

    def add_user(self, body: schema.UserCreate, by: str) -> schema.User:
        """A new account; :class:`Conflict` if the name is taken."""
        with self._store.reading() as s:
            if s.scalar(select(UserRow.id).where(UserRow.name == body.name)) is not None:
                raise Conflict(f"user {body.name!r} exists")
        password_hash = self._hash(body.password)  # outside any transaction
        with self._store.writing() as s:
            if s.scalar(select(UserRow.id).where(UserRow.name == body.name)) is not None:
                raise Conflict(f"user {body.name!r} exists")
            row = UserRow(
                name=body.name, role=body.role, password_hash=password_hash, disabled=False,
                created_utc=_stamp(_now()), created_by=by, failed_logins=0,
            )  # fmt: skip
            s.add(row)
            s.flush()
            return _user(row)

    def list_users(self) -> list[schema.User]:
        with self._store.reading() as s:
            return [_user(r) for r in s.scalars(select(UserRow).order_by(UserRow.name))]

    def get_user(self, name: str) -> schema.User:
        with self._store.reading() as s:
            return _user(self._user_row(s, name))

    @staticmethod
    def _user_row(s: orm.Session, name: str) -> UserRow:
        row = s.scalar(select(UserRow).where(UserRow.name == name))
        if row is None:
            raise NotFound(f"user {name!r} does not exist")
        return row

    def change_user(self, name: str, change: schema.UserChange, by: str) -> tuple[schema.User, schema.User]:
        """Apply an admin's change; returns (before, after). Disabling, demoting or resetting the password of
        an account ends its logins (and their open sockets are told). The last enabled admin cannot be disabled
        or demoted (:class:`Conflict`). An unlock also clears this process's throttle of the name."""
        new_hash = None if change.password is None else self._hash(change.password)  # outside any transaction
        ended: list[int] = []
        with self._store.writing() as s:
            row = self._user_row(s, name)
            before = _user(row)
            losing_admin = row.role == "admin" and (
                (change.role is not None and change.role != "admin") or change.disabled is True
            )
            if losing_admin and not row.disabled:
                enabled_admins = (UserRow.role == "admin", UserRow.disabled.is_(False))
                admins = s.scalar(select(func.count()).select_from(UserRow).where(*enabled_admins))
                if (admins or 0) <= 1:
                    raise Conflict(f"{name!r} is the last admin: make another admin first")
            end_logins = False
            if change.role is not None and change.role != row.role:
                row.role, end_logins = change.role, True
            if change.disabled is not None and change.disabled != row.disabled:
                row.disabled, end_logins = change.disabled, end_logins or change.disabled
            if change.unlock:
                row.failed_logins, row.locked_until_utc = 0, None
            if new_hash is not None:
                row.password_hash, end_logins = new_hash, True
            if end_logins:
                ended = self._end_logins(s, row.id)
            s.flush()
            after = _user(row)
        if change.unlock:
            self.throttle.unlock(name)
        why = "password reset" if new_hash is not None else "disabled" if after.disabled else "role changed"
        self.watch.end(ended, f"login ended: account {why}")
        return before, after

    # --- logins -------------------------------------------------------------------------------------

    def login(self, name: str, password: str, address: str = "unknown", now: dt.datetime | None = None) -> Login:
        """Check the password and open a login session, all in the calling thread; :class:`LoginFailed` if
        refused (:data:`REFUSED`, counted by the throttle and in the account's row). The server uses
        :meth:`login_async`."""
        attempt = self._begin_login(name, address)
        return self._finish_login(attempt, self._check(attempt, password), now)

    async def login_async(
        self, name: str, password: str, address: str = "unknown", now: dt.datetime | None = None
    ) -> Login:
        """:meth:`login` for the event loop: the database's read and write in the shared worker threads (short),
        the verification in a pool of its own of ``hash_slots`` threads, or of one thread for the attempts the
        throttle holds back (so that a flood of those queues behind itself, not ahead of the others); every
        hash takes one of the process's ``hash_slots``. A flood of logins thus never blocks the loop, takes
        more than its share of the cores, nor the threads the other routes need."""
        if self._pools is None:
            self._pools = (CapacityLimiter(self._hash_slot_count), CapacityLimiter(1))
        attempt = await anyio.to_thread.run_sync(self._begin_login, name, address)
        pool = self._pools[1] if attempt.waits else self._pools[0]
        checked = await anyio.to_thread.run_sync(self._check, attempt, password, limiter=pool)
        return await anyio.to_thread.run_sync(self._finish_login, attempt, checked, now)

    def _begin_login(self, name: str, address: str) -> _Attempt:
        with self._store.reading() as s:
            row = s.scalar(select(UserRow).where(UserRow.name == name))
            found = None if row is None else (row.id, row.password_hash, row.failed_logins, row.locked_until_utc)
        if found is not None and found[2] == 0 and found[3] is None:
            self.throttle.forget_name(name)  # an admin unlocked it (perhaps from the command line), or a good login
        waits = self.throttle.wait(address, name) > 0
        return _Attempt(name, address, None if found is None else found[0], None if found is None else found[1], waits)

    def _check(self, attempt: _Attempt, password: str) -> tuple[bool, str | None]:
        """The verification (always exactly one), and the password's new hash if the hasher's parameters
        changed since it was made; no database."""
        ok = self._verify(attempt.password_hash or self._dummy_hash, password)
        ok = ok and attempt.password_hash is not None and not attempt.waits
        rehash = None
        if ok and attempt.password_hash is not None and self._hasher.check_needs_rehash(attempt.password_hash):
            rehash = self._hash(password)
        return ok, rehash

    def _finish_login(self, attempt: _Attempt, checked: tuple[bool, str | None], now: dt.datetime | None) -> Login:
        now = now or _now()
        ok, rehash = checked
        if not ok:
            if attempt.waits:  # an attempt held back was not checked: it is no further failure
                wait = self.throttle.wait(attempt.address, attempt.name)
                raise LoginFailed(
                    _held_back(wait), "held back by the failed-login throttle (not checked)", retry_after_s=wait
                )
            self._failed(attempt.name, attempt.address, now)
            wait = self.throttle.wait(attempt.address, attempt.name)
            left = self.throttle.tries_left(attempt.address, attempt.name)
            raise LoginFailed(_refusal(wait, left, self.throttle.free), "wrong name or password", retry_after_s=wait)
        with self._store.writing() as s:
            row = s.get(UserRow, attempt.user_id)
            if row is None or row.password_hash != attempt.password_hash:
                raise LoginFailed(REFUSED, "the account was removed or its password changed during the login")
            if row.disabled:
                raise LoginFailed(f"account {attempt.name!r} is disabled: ask an admin")
            if rehash is not None:
                row.password_hash = rehash
            row.failed_logins, row.locked_until_utc, row.last_login_utc = 0, None, _stamp(now)
            token, csrf = secrets.token_urlsafe(32), secrets.token_urlsafe(32)
            login = LoginRow(
                user_id=row.id, token_sha256=_sha256(token), csrf_token=csrf, created_utc=_stamp(now),
                seen_utc=_stamp(now), expires_utc=_stamp(now + self.login_length),
            )  # fmt: skip
            s.add(login)
            s.flush()
            done = Login(_user(row), login.id, csrf, token)
        self.throttle.succeeded(attempt.address, attempt.name)
        return done

    def _failed(self, name: str, address: str, now: dt.datetime) -> None:
        """Count a failed check of ``name``'s password from ``address``: in the throttle, and in the account's
        row (the same statement for a name that does not exist, which changes nothing)."""
        self.throttle.failed(address, name)
        wait = self.throttle.name_wait(name)
        until = _stamp(now + dt.timedelta(seconds=wait)) if wait > 0 else None
        with self._store.writing() as s:
            s.execute(
                update(UserRow).where(UserRow.name == name)
                .values(failed_logins=UserRow.failed_logins + 1, locked_until_utc=until)
            )  # fmt: skip

    def identify(self, token: str, now: dt.datetime | None = None) -> Login | None:
        """The login whose cookie token this is, if it is open, unexpired and its user enabled."""
        now = now or _now()
        with self._store.reading() as s:
            found = s.execute(
                select(LoginRow, UserRow).join(UserRow, UserRow.id == LoginRow.user_id)
                .where(LoginRow.token_sha256 == _sha256(token))
            ).first()  # fmt: skip
            if found is None:
                return None
            login, user = found
            if login.ended_utc is not None or user.disabled or dt.datetime.fromisoformat(login.expires_utc) <= now:
                return None
            return Login(_user(user), login.id, login.csrf_token)

    def logout(self, login_id: int) -> None:
        """End a login; its open sockets are told."""
        with self._store.writing() as s:
            s.execute(update(LoginRow).where(LoginRow.id == login_id).values(ended_utc=_stamp(_now())))
        self.watch.end([login_id], "logged out")

    def change_password(self, name: str, current: str, new: str, address: str = "unknown") -> None:
        """Change one's own password (the current one checked, and a wrong one counted by the throttle as a
        failed login from ``address``); every login of the user ends and their open sockets are told."""
        wait = self.throttle.wait(address, name)
        with self._store.reading() as s:
            old_hash = self._user_row(s, name).password_hash
        right = self._verify(old_hash, current)
        if wait > 0:
            raise LoginFailed(f"too many wrong passwords: try again in {wait:.0f} s")
        if not right:
            self._failed(name, address, _now())
            raise LoginFailed("the current password is wrong")
        if current == new:
            raise Conflict("the new password is the current one")
        new_hash = self._hash(new)  # outside any transaction
        with self._store.writing() as s:
            row = self._user_row(s, name)
            if row.password_hash != old_hash:
                raise Conflict("the password was changed meanwhile: log in again")
            row.password_hash = new_hash
            ended = self._end_logins(s, row.id)
        self.watch.end(ended, "login ended: password changed")

    def open_logins(self, login_ids: Iterable[int], now: dt.datetime | None = None) -> set[int]:
        """Which of ``login_ids`` are still open (not ended, unexpired, their user enabled)."""
        ids, now = list(login_ids), now or _now()
        if not ids:
            return set()
        with self._store.reading() as s:
            found = s.execute(
                select(LoginRow.id, LoginRow.ended_utc, LoginRow.expires_utc, UserRow.disabled)
                .join(UserRow, UserRow.id == LoginRow.user_id).where(LoginRow.id.in_(ids))
            ).all()  # fmt: skip
        return {
            i for i, ended, expires, disabled in found
            if ended is None and not disabled and dt.datetime.fromisoformat(expires) > now
        }  # fmt: skip

    @staticmethod
    def _end_logins(s: orm.Session, user_id: int) -> list[int]:
        """End every open login of the user; their ids (the caller tells their sockets after the commit)."""
        ids = list(s.scalars(select(LoginRow.id).where(LoginRow.user_id == user_id, LoginRow.ended_utc.is_(None))))
        s.execute(
            update(LoginRow).where(LoginRow.user_id == user_id, LoginRow.ended_utc.is_(None))
            .values(ended_utc=_stamp(_now()))
        )  # fmt: skip
        return ids

    # --- device tokens ------------------------------------------------------------------------------

    def issue_device_token(self, session_id: int, by: str) -> schema.DeviceToken:
        """A new token for session ``session_id``'s device; the answer is the only place the token appears."""
        token = secrets.token_urlsafe(32)
        with self._store.writing() as s:
            row = DeviceTokenRow(
                session_id=session_id, token_sha256=_sha256(token), prefix=token[:6], created_utc=_stamp(_now()),
                created_by=by,
            )  # fmt: skip
            s.add(row)
            s.flush()
            return _device_token(row, token)

    def list_device_tokens(self, session_id: int) -> list[schema.DeviceToken]:
        with self._store.reading() as s:
            q = select(DeviceTokenRow).where(DeviceTokenRow.session_id == session_id).order_by(DeviceTokenRow.id)
            return [_device_token(r) for r in s.scalars(q)]

    def revoke_device_token(self, session_id: int, token_id: int, by: str) -> schema.DeviceToken:
        with self._store.writing() as s:
            row = s.get(DeviceTokenRow, token_id) if 0 < token_id <= schema.INT64_MAX else None
            if row is None or row.session_id != session_id:
                raise NotFound(f"session {session_id} has no device token {token_id}")
            if row.revoked_utc is None:
                row.revoked_utc, row.revoked_by = _stamp(_now()), by
            s.flush()
            return _device_token(row)

    def device_token_id(self, session_id: int, token: str) -> int | None:
        """The id of ``token`` if it is an unrevoked token of session ``session_id``, else None."""
        digest = _sha256(token)
        with self._store.reading() as s:
            row = s.scalar(select(DeviceTokenRow).where(DeviceTokenRow.token_sha256 == digest))
            ok = (
                row is not None
                and row.session_id == session_id
                and row.revoked_utc is None
                and hmac.compare_digest(row.token_sha256, digest)
            )
            return row.id if ok and row is not None else None

    # --- assistance limits --------------------------------------------------------------------------

    def limits(self, subject_id: int) -> schema.SubjectLimits | None:
        with self._store.reading() as s:
            row = s.get(LimitsRow, subject_id)
            return None if row is None else schema.SubjectLimits.model_validate(row, from_attributes=True)

    def set_limits(self, subject_id: int, limits: schema.AssistanceLimits, by: str) -> schema.SubjectLimits:
        self._store.get_subject(subject_id)  # NotFound for a subject that does not exist
        with self._store.writing() as s:
            row = s.get(LimitsRow, subject_id) or LimitsRow(subject_id=subject_id)
            for field, value in limits.model_dump().items():
                setattr(row, field, value)
            row.set_by, row.set_utc = by, _stamp(_now())
            s.add(row)
            s.flush()
            return schema.SubjectLimits.model_validate(row, from_attributes=True)
