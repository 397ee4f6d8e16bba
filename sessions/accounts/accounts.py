"""Accounts: users with argon2id password hashes, login sessions with lockout, device tokens, and the assistance
limits a clinician sets for experimenters.

One :class:`Accounts` per server, over the :class:`~sessions.store.Store`'s database (its tables are
:mod:`sessions.accounts.tables`). Every method is one transaction. Times are ISO-8601 UTC.

Choices:

- Passwords: argon2id through argon2-cffi's :class:`~argon2.PasswordHasher` with its defaults (RFC 9106's
  second recommended profile, 64 MiB, 3 passes), rehashed on the next login when those defaults change.
- A login that fails ``lockout_after`` times in a row locks the account for ``lockout_minutes``; a good login
  resets the count; an admin may unlock at once. An unknown name costs the same argon2 verification as a
  known one, so the answer's timing does not tell whether a name exists.
- Login sessions: a 256-bit random token in the cookie, stored as its SHA-256; each has its own CSRF token
  (the synchronizer-token pattern, OWASP) and ends ``login_hours`` after it began (a clinic's day), or at
  logout, or when the password changes (every login of the user ends).
- Device tokens: 256-bit random, one session each, shown once, stored as SHA-256, revocable.
"""

from __future__ import annotations

import datetime as dt
import functools
import hashlib
import hmac
import secrets
from dataclasses import dataclass

from argon2 import PasswordHasher
from argon2.exceptions import InvalidHashError, VerificationError, VerifyMismatchError
from sqlalchemy import func, orm, select, update

from sessions import schema
from sessions.accounts.tables import DeviceTokenRow, LimitsRow, LoginRow, UserRow
from sessions.store import Conflict, NotFound, Store

__all__ = ["Accounts", "Login", "LoginFailed"]

#: A fixed hash verified for unknown names, so that they take as long as known ones.
_DUMMY_PASSWORD = "not a password of anyone's"


class LoginFailed(PermissionError):
    """A login was refused; the message says why in words fit to show (it never says whether a name exists,
    except that a locked account says it is locked)."""


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
        lockout_after: failed logins in a row that lock an account.
        lockout_minutes: how long the lock lasts.
        login_hours: how long a login session lasts.
        hasher: the password hasher (argon2-cffi's defaults unless given; tests may pass a cheaper one).
    """

    def __init__(
        self,
        store: Store,
        *,
        lockout_after: int = 5,
        lockout_minutes: float = 15.0,
        login_hours: float = 12.0,
        hasher: PasswordHasher | None = None,
    ) -> None:
        if lockout_after < 1 or lockout_minutes <= 0 or login_hours <= 0:
            raise ValueError("lockout_after, lockout_minutes and login_hours must be positive")
        self._store = store
        self.lockout_after = lockout_after
        self.lockout = dt.timedelta(minutes=lockout_minutes)
        self.login_length = dt.timedelta(hours=login_hours)
        self._hasher = hasher or PasswordHasher()

    @functools.cached_property
    def _dummy_hash(self) -> str:
        """The hash an unknown name's password is checked against: made at the first such login, not with every
        :class:`Accounts` (an argon2 hash costs 64 MiB and tens of milliseconds)."""
        return self._hasher.hash(_DUMMY_PASSWORD)

    # --- users --------------------------------------------------------------------------------------

    def count_users(self) -> int:
        with self._store.reading() as s:
            return int(s.scalar(select(func.count()).select_from(UserRow)) or 0)

    def add_user(self, body: schema.UserCreate, by: str) -> schema.User:
        """A new account; :class:`Conflict` if the name is taken."""
        with self._store.writing() as s:
            if s.scalar(select(UserRow.id).where(UserRow.name == body.name)) is not None:
                raise Conflict(f"user {body.name!r} exists")
            row = UserRow(
                name=body.name, role=body.role, password_hash=self._hasher.hash(body.password), disabled=False,
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
        an account ends its logins. The last enabled admin cannot be disabled or demoted (:class:`Conflict`)."""
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
            if change.password is not None:
                row.password_hash, end_logins = self._hasher.hash(change.password), True
            if end_logins:
                self._end_logins(s, row.id)
            s.flush()
            return before, _user(row)

    # --- logins -------------------------------------------------------------------------------------

    def login(self, name: str, password: str, now: dt.datetime | None = None) -> Login:
        """Check the password and open a login session; :class:`LoginFailed` if refused (the failure is
        counted, and the account locked after ``lockout_after`` in a row)."""
        now = now or _now()
        with self._store.writing() as s:
            row = s.scalar(select(UserRow).where(UserRow.name == name))
            if row is None:
                self._verify(self._dummy_hash, password)
                raise LoginFailed("wrong name or password")
            if row.locked_until_utc is not None and dt.datetime.fromisoformat(row.locked_until_utc) > now:
                until = row.locked_until_utc
                raise LoginFailed(f"account {name!r} is locked after repeated failed logins until {until}")
            if not self._verify(row.password_hash, password):
                row.failed_logins += 1
                if row.failed_logins >= self.lockout_after:
                    row.locked_until_utc = _stamp(now + self.lockout)
                failed = LoginFailed("wrong name or password")
            elif row.disabled:
                failed = LoginFailed(f"account {name!r} is disabled: ask an admin")
            else:
                if self._hasher.check_needs_rehash(row.password_hash):
                    row.password_hash = self._hasher.hash(password)
                row.failed_logins, row.locked_until_utc, row.last_login_utc = 0, None, _stamp(now)
                token, csrf = secrets.token_urlsafe(32), secrets.token_urlsafe(32)
                login = LoginRow(
                    user_id=row.id, token_sha256=_sha256(token), csrf_token=csrf, created_utc=_stamp(now),
                    seen_utc=_stamp(now), expires_utc=_stamp(now + self.login_length),
                )  # fmt: skip
                s.add(login)
                s.flush()
                return Login(_user(row), login.id, csrf, token)
        raise failed  # after the commit: the count (and the lock) are kept

    def _verify(self, password_hash: str, password: str) -> bool:
        try:
            return self._hasher.verify(password_hash, password)
        except (VerifyMismatchError, VerificationError, InvalidHashError):
            return False

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
        with self._store.writing() as s:
            s.execute(update(LoginRow).where(LoginRow.id == login_id).values(ended_utc=_stamp(_now())))

    def change_password(self, name: str, current: str, new: str) -> None:
        """Change one's own password (the current one checked); every login of the user ends."""
        with self._store.writing() as s:
            row = self._user_row(s, name)
            if not self._verify(row.password_hash, current):
                raise LoginFailed("the current password is wrong")
            if current == new:
                raise Conflict("the new password is the current one")
            row.password_hash = self._hasher.hash(new)
            self._end_logins(s, row.id)

    @staticmethod
    def _end_logins(s: orm.Session, user_id: int) -> None:
        s.execute(
            update(LoginRow).where(LoginRow.user_id == user_id, LoginRow.ended_utc.is_(None))
            .values(ended_utc=_stamp(_now()))
        )  # fmt: skip

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
