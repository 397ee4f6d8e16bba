"""The server's one settings object, read from ``GAITSCOPE_*`` environment variables."""

from __future__ import annotations

import ipaddress
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field, field_validator, model_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

from server.origin import LOOPBACK_HOSTS, allowed_host, allowed_hosts_for


class Settings(BaseSettings):
    """Ports, folders and the database; defaults run everything on this machine with no services.

    Attributes:
        host: address to bind; loopback by default. Anything else is refused in production until
            login arrives, and announced loudly in development.
        port: HTTP port of the dashboard and API.
        viser_port: port of the 3D leg view (viser runs its own server; it may move to a free port).
        data_dir: recordings, uploads and models live here; created if missing.
        database_url: SQLAlchemy URL; default a SQLite file in ``data_dir``.
        demo: on an empty database, create a demo subject and start a simulated session.
        max_upload_mb: largest accepted upload.
        upload_chunk_kb: size of one upload chunk.
        slow_client_s: a browser that cannot take its stream for this long is disconnected (1013).
        allowed_hosts: the names (and addresses) the dashboard and the leg view may be reached at;
            any other ``Host`` is refused, which defeats DNS rebinding (:mod:`server.origin`). Names
            without ports; the environment gives them comma-separated
            (``GAITSCOPE_ALLOWED_HOSTS=127.0.0.1,localhost,::1,gaitlab.local``). Default the loopback
            names; ``host`` is always added unless it is a wildcard (``0.0.0.0``, ``::``).
    """

    model_config = SettingsConfigDict(env_prefix="GAITSCOPE_", extra="ignore")

    environment: Literal["development", "production"] = "development"
    host: str = "127.0.0.1"
    port: int = Field(default=8000, ge=0, le=65535)
    viser_port: int = Field(default=8081, ge=0, le=65535)
    leg_view: bool = True
    data_dir: Path = Path("gaitscope-data")
    database_url: str = ""
    demo: bool = True
    max_upload_mb: int = Field(default=512, ge=1, le=16384)
    upload_chunk_kb: int = Field(default=4096, ge=64, le=65536)
    slow_client_s: float = Field(default=10.0, gt=0.0, le=300.0)
    allowed_hosts: Annotated[list[str], NoDecode] = Field(default_factory=lambda: list(LOOPBACK_HOSTS))

    @field_validator("allowed_hosts", mode="before")
    @classmethod
    def _split_hosts(cls, value: Any) -> Any:
        # Comma-separated rather than JSON in the environment: "[::1]" would read as a JSON list.
        return [h.strip() for h in value.split(",") if h.strip()] if isinstance(value, str) else value

    @field_validator("allowed_hosts")
    @classmethod
    def _canonical_hosts(cls, value: list[str]) -> list[str]:
        return [allowed_host(h) for h in value]

    @model_validator(mode="after")
    def _defaults_and_safety(self) -> Settings:
        if not self.database_url:
            self.database_url = f"sqlite:///{(self.data_dir / 'gaitscope.db').as_posix()}"
        self.allowed_hosts = allowed_hosts_for(self.host, self.allowed_hosts)
        if self.environment == "production" and not self.is_loopback:
            raise ValueError(
                f"refusing to listen on {self.host} in production: gaitscope has no login yet; "
                "bind 127.0.0.1 and put an authenticating proxy in front"
            )
        return self

    @property
    def is_loopback(self) -> bool:
        if self.host == "localhost":
            return True
        try:
            return ipaddress.ip_address(self.host).is_loopback
        except ValueError:
            return False
