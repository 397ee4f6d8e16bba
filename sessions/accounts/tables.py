"""The accounts' tables: users, their login sessions, device tokens and the experimenters' assistance limits.

Declared on :data:`gaitscope.sessions.store.Base`, so that one database (and one chain of Alembic migrations,
``sessions/migrations``) holds them beside the subjects and sessions. Secrets are never stored: a password as
its argon2id hash, a login session's and a device's token as their SHA-256 (they are 256-bit random, so a fast
hash is enough; an attacker with the table learns nothing he could log in with).
"""

from __future__ import annotations

from sqlalchemy import ForeignKey, String, Text
from sqlalchemy.orm import Mapped, mapped_column

from gaitscope.sessions.store import Base


class UserRow(Base):
    __tablename__ = "users"

    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(32), unique=True)
    role: Mapped[str] = mapped_column(String(16))
    password_hash: Mapped[str] = mapped_column(Text)
    disabled: Mapped[bool] = mapped_column(default=False)
    created_utc: Mapped[str] = mapped_column(String(40))
    created_by: Mapped[str] = mapped_column(String(64))
    last_login_utc: Mapped[str | None] = mapped_column(String(40))
    failed_logins: Mapped[int] = mapped_column(default=0)
    locked_until_utc: Mapped[str | None] = mapped_column(String(40))


class LoginRow(Base):
    """A login session: the cookie's token (hashed), its CSRF token, when it ends."""

    __tablename__ = "logins"

    id: Mapped[int] = mapped_column(primary_key=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id"), index=True)
    token_sha256: Mapped[str] = mapped_column(String(64), unique=True)
    csrf_token: Mapped[str] = mapped_column(String(64))
    created_utc: Mapped[str] = mapped_column(String(40))
    seen_utc: Mapped[str] = mapped_column(String(40))
    expires_utc: Mapped[str] = mapped_column(String(40))
    ended_utc: Mapped[str | None] = mapped_column(String(40))


class DeviceTokenRow(Base):
    __tablename__ = "device_tokens"

    id: Mapped[int] = mapped_column(primary_key=True)
    session_id: Mapped[int] = mapped_column(ForeignKey("sessions.id"), index=True)
    token_sha256: Mapped[str] = mapped_column(String(64), unique=True)
    prefix: Mapped[str] = mapped_column(String(16))
    created_utc: Mapped[str] = mapped_column(String(40))
    created_by: Mapped[str] = mapped_column(String(64))
    revoked_utc: Mapped[str | None] = mapped_column(String(40))
    revoked_by: Mapped[str | None] = mapped_column(String(64))


class LimitsRow(Base):
    """A subject's assistance limits for experimenters (one row per subject, replaced when a clinician sets them)."""

    __tablename__ = "assistance_limits"

    subject_id: Mapped[int] = mapped_column(ForeignKey("subjects.id"), primary_key=True)
    torque_gain: Mapped[float]
    max_torque_Nm: Mapped[float]
    intent_gain_boost: Mapped[float]
    set_by: Mapped[str] = mapped_column(String(64))
    set_utc: Mapped[str] = mapped_column(String(40))
