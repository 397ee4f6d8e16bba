"""The server's one settings object, read from ``GAITSCOPE_*`` environment variables."""

from __future__ import annotations

import ipaddress
import socket
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field, SecretStr, field_validator, model_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

from gaitscope.server.origin import LOOPBACK_HOSTS, allowed_host, allowed_hosts_for
from gaitscope.sessions.live.gp_learning import DUTY, NICE
from gaitscope.sessions.schema import MAX_FRAME_BYTES


class Settings(BaseSettings):
    """Ports, folders and the database; defaults run everything on this machine with no services.

    Attributes:
        host: address to bind; loopback by default. Anything else needs accounts on and TLS (the server's
            own, or a proxy's).
        port: HTTP port of the dashboard and API.
        viser_port: port of the 3D leg view (viser runs its own server; it may move to a free port).
        data_dir: recordings, uploads and models live here; created if missing.
        database_url: SQLAlchemy URL; default a SQLite file in ``data_dir``.
        demo: on an empty database, create a demo subject and start a simulated session.
        max_upload_mb: largest accepted upload.
        upload_chunk_kb: size of one upload chunk.
        max_open_uploads: uploads open at once (created, not yet finished or cancelled); one more is
            refused (429).
        upload_idle_s: an open upload without a request for this long is dropped with its bytes.
        upload_min_free_mb: a new upload is refused (507) when the data folder's disk would have less
            than this many MiB free once every open upload and running import is written; at least
            ``disk_warn_mb`` by default, so that an upload never makes a live session warn.
        slow_client_s: a browser that cannot take its stream for this long is disconnected (1013).
        ws_max_kb: the largest message (KiB) a websocket reads: a longer one closes the socket (1009) as soon
            as its header arrives, before it is read whole. At least a device's largest frame
            (:data:`~gaitscope.sessions.schema.MAX_FRAME_BYTES`, 16 KiB: four times a frame of every channel); the
            64 KiB default leaves a frame between the two refused with a short notice instead. Browsers
            send the server nothing larger.
        disk_warn_mb: below this many MiB free on the data folder's disk a running session warns
            (:class:`~sessions.live.disk.DiskGuard`), saying how many minutes of recording are left at its rate;
            512 MiB is 28 to 117 minutes of one 200 Hz session, from every channel to the walking set
            (measured: ``python -m gaitscope.server.bench.disk_rate``, docs/dashboard.md "Disk space").
        disk_stop_mb: below this many MiB free the recording is finished and the session stopped;
            at most ``disk_warn_mb``. 128 MiB leaves room to finish the file's index and for crash
            recovery's copy of a recording of about an hour.
        allowed_hosts: the names (and addresses) the dashboard and the leg view may be reached at;
            any other ``Host`` is refused, which defeats DNS rebinding (:mod:`gaitscope.server.origin`). Names
            without ports; the environment gives them comma-separated
            (``GAITSCOPE_ALLOWED_HOSTS=127.0.0.1,localhost,::1,gaitlab.local``). Default the loopback
            names; ``host`` is always added unless it is a wildcard (``0.0.0.0``, ``::``).
        auth: accounts on: every request needs a login (or, for a device, its session's token), roles are
            checked and the audit trail names the user. Off (the default, loopback only): nobody logs in and
            every caller is ``local`` with an admin's rights, announced at start-up.
        tls_cert, tls_key: PEM files; with both, the server speaks HTTPS itself.
        behind_tls_proxy: a TLS-terminating proxy (nginx, caddy, the hospital's) is in front: the login cookie
            is marked Secure and the server trusts the proxy's forwarded scheme and client address.
        login_hours: a login lasts this long (a clinic's day).
        lockout_after, lockout_minutes: failed logins are throttled, never locked out: after ``lockout_after``
            failures of one address at one name (4 x that of one address at any names, or at one name from
            any addresses that failed at it) the next attempt waits 1 s, doubling with each failure up to
            ``lockout_minutes`` (:mod:`gaitscope.sessions.accounts.throttle`; ``docs/api.md``).
        node: this process's name in a shared database (several gaitscope processes on one PostgreSQL):
            stored with each session it runs; at start-up it recovers only its own sessions after a crash, and
            it refuses to stop another's. Default ``<host name>:<port>``: stable across restarts, distinct for
            processes on other machines or ports.
        cluster: this process is one node of several behind a routing proxy (``gaitscope serve --workers N``,
            docker compose; ``sessions/cluster``): it registers in the shared database, beats every second,
            answers the proxy's ``/api/cluster/route`` and takes over the sessions of a node whose beat stops.
            Needs PostgreSQL. Off (the default): one process, nothing of this.
        node_address: ``host:port`` at which the proxy reaches this node (default ``<host>:<port>``).
        node_timeout_s: seconds without a beat after which a node is gone and another takes its sessions over.
        audit_key: the audit trail's key (``GAITSCOPE_AUDIT_KEY``, at least 32 characters): every entry carries an
            HMAC under it (:mod:`sessions.audit.key`). Unset: the data folder's ``audit.key``, created (0600) at
            first start. Processes sharing one database need the same key: set it on each.
        gp_fit_duty: the fraction of its time the GP-EKF's shared fitting worker may spend fitting
            (:class:`~gaitscope.sessions.live.gp_learning.GPTrainer`): with many learning sessions on few cores,
            each retrains less often than seed 003's every 5 steps, so that the fits leave the cores to
            the sample loops. 1.0: back to back.
        gp_fit_nice: how much lower the fitting worker's priority is than the server's (a Unix nice increment,
            0-19, applied after it imported GPy; default 10: 19 starved its fits on a busy machine).
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
    max_open_uploads: int = Field(default=8, ge=1, le=256)
    upload_idle_s: float = Field(default=900.0, gt=0.0, le=86400.0)
    upload_min_free_mb: int = Field(default=512, ge=0)
    slow_client_s: float = Field(default=10.0, gt=0.0, le=300.0)
    ws_max_kb: int = Field(default=64, ge=MAX_FRAME_BYTES // 1024, le=16 * 1024)
    disk_warn_mb: int = Field(default=512, ge=1)
    disk_stop_mb: int = Field(default=128, ge=1)
    gp_fit_duty: float = Field(default=DUTY, gt=0.0, le=1.0)
    gp_fit_nice: int = Field(default=NICE, ge=0, le=19)
    node: str = Field(default="", max_length=128)
    cluster: bool = False
    node_address: str = Field(default="", max_length=256)
    node_timeout_s: float = Field(default=10.0, gt=2.0, le=600.0)
    auth: bool = False
    tls_cert: Path | None = None
    tls_key: Path | None = None
    behind_tls_proxy: bool = False
    login_hours: float = Field(default=12.0, gt=0.0, le=24.0 * 30)
    lockout_after: int = Field(default=5, ge=1, le=100)
    lockout_minutes: float = Field(default=15.0, gt=0.0, le=24.0 * 60)
    allowed_hosts: Annotated[list[str], NoDecode] = Field(default_factory=lambda: list(LOOPBACK_HOSTS))
    audit_key: SecretStr | None = None

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
        if not self.node:
            self.node = f"{socket.gethostname()}:{self.port}"
        if not self.node_address:
            self.node_address = f"{self.host}:{self.port}"
        if not self.database_url:
            self.database_url = f"sqlite:///{(self.data_dir / 'gaitscope.db').as_posix()}"
        if self.cluster and not self.database_url.startswith("postgresql"):
            raise ValueError(
                "a cluster node (GAITSCOPE_CLUSTER=true, serve --workers) needs the shared PostgreSQL database "
                "(GAITSCOPE_DATABASE_URL=postgresql+psycopg://...): one SQLite file is not shared by processes"
            )
        self.allowed_hosts = allowed_hosts_for(self.host, self.allowed_hosts)
        if (self.tls_cert is None) != (self.tls_key is None):
            raise ValueError("tls_cert and tls_key go together: give both (PEM files) or neither")
        if not self.is_loopback:
            missing = [
                *([] if self.auth else ["accounts (GAITSCOPE_AUTH=true)"]),
                *([] if self.tls else ["TLS (GAITSCOPE_TLS_CERT and _KEY, or GAITSCOPE_BEHIND_TLS_PROXY=true)"]),
            ]
            if missing:
                raise ValueError(f"refusing to listen on {self.host} without {' and '.join(missing)}: bind 127.0.0.1")
        return self

    @property
    def tls(self) -> bool:
        """The browser reaches the server over TLS (its own, or a proxy's)."""
        return self.behind_tls_proxy or self.tls_cert is not None

    @model_validator(mode="after")
    def _disk_thresholds(self) -> Settings:
        if self.disk_stop_mb > self.disk_warn_mb:
            raise ValueError(f"disk_stop_mb ({self.disk_stop_mb}) must not be above disk_warn_mb ({self.disk_warn_mb})")
        return self

    @property
    def is_loopback(self) -> bool:
        if self.host == "localhost":
            return True
        try:
            return ipaddress.ip_address(self.host).is_loopback
        except ValueError:
            return False
