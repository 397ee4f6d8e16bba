"""``gaitscope serve --workers N``: N gaitscope nodes on this machine behind nginx, on one PostgreSQL database.

The supervisor (this module) starts N ``gaitscope serve`` processes on loopback, each a cluster node
(``GAITSCOPE_CLUSTER=true``, named ``<base>-<i>`` where base is ``GAITSCOPE_NODE`` or the host name), waits
until each answers, writes nginx's configuration (:mod:`gaitscope.server.proxy`) and runs nginx in the
foreground on the address the single process would have used. It prints the URL once nginx answers.

A node that exits is started again under the same name and port after a pause (1 s, doubling to 30 s while
it keeps failing); at start it recovers what it ran, as after any crash. If its beat stopped for longer than
the timeout, another node has already stopped its sessions and recovered their recordings
(:mod:`gaitscope.sessions.cluster`). If nginx exits, everything stops. SIGTERM or SIGINT stops nginx, then
the nodes (each finishes its recordings), then returns.

Only the first node runs the 3D leg view (on ``viser_port``) and the demo session; every node serves the
dashboard and the API. Each node's output goes to ``<data dir>/cluster/<name>.log``.
"""

from __future__ import annotations

import functools
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Final

from gaitscope.server.proxy import ProxyNode, nginx_config
from gaitscope.server.settings import Settings

#: Seconds a node or nginx gets to answer after it starts (a first start compiles the kernels).
START_TIMEOUT_S: Final = 180.0
#: Seconds the nodes get to stop (finish their recordings) before they are killed.
STOP_TIMEOUT_S: Final = 30.0
LOOPBACK: Final = "127.0.0.1"


class WorkersError(RuntimeError):
    """The workers could not start: the message says what is missing or what failed."""


def find_nginx() -> str:
    """The nginx executable (``GAITSCOPE_NGINX``, else on the PATH or in /usr/sbin)."""
    for candidate in (os.environ.get("GAITSCOPE_NGINX"), shutil.which("nginx"), "/usr/sbin/nginx"):
        if candidate and os.access(candidate, os.X_OK):
            return candidate
    raise WorkersError("serve --workers routes through nginx, which is not installed (Debian: apt-get install nginx)")


def nginx_command(nginx: str, run_dir: Path, *flags: str) -> list[str]:
    """nginx on ``run_dir/nginx.conf``, its prefix and start-up error log in ``run_dir`` (not /var/log/nginx)."""
    conf, errors = run_dir / "nginx.conf", run_dir / "nginx-error.log"
    return [nginx, "-p", str(run_dir), "-e", str(errors), "-c", str(conf), *flags]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind((LOOPBACK, 0))
        return int(s.getsockname()[1])


def _listens(host: str, port: int) -> bool:
    try:
        socket.create_connection((host, port), timeout=1).close()
        return True
    except OSError:
        return False


def _answers(url: str) -> bool:
    try:
        urllib.request.urlopen(url, timeout=1).close()
        return True
    except OSError:
        return False


@dataclass
class _Child:
    name: str
    cmd: list[str]
    env: dict[str, str]
    log_path: Path
    proc: subprocess.Popen[bytes] | None = None
    log: IO[bytes] | None = None
    restarts: int = 0
    next_start: float = 0.0
    pause_s: float = 1.0

    def start(self) -> None:
        if self.log is None:
            self.log = self.log_path.open("ab")
        self.proc = subprocess.Popen(self.cmd, env=self.env, stdout=self.log, stderr=subprocess.STDOUT)

    def stop(self, sig: int = signal.SIGTERM) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(sig)

    def wait(self, deadline: float) -> None:
        if self.proc is None:
            return
        try:
            self.proc.wait(timeout=max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout=10)


@dataclass
class Workers:
    """The nodes and nginx of one ``serve --workers N`` (module docstring)."""

    settings: Settings
    count: int
    log_level: str = "info"
    say: Callable[[str], None] = field(default=lambda text: print(text, flush=True))
    nodes: list[_Child] = field(default_factory=list)
    nginx: _Child | None = None
    _stopping: bool = False

    def __post_init__(self) -> None:
        if not 1 <= self.count <= 64:
            raise WorkersError(f"--workers {self.count}: between 1 and 64")
        if not self.settings.database_url.startswith("postgresql"):
            raise WorkersError(
                "serve --workers needs the shared PostgreSQL database (GAITSCOPE_DATABASE_URL=postgresql+psycopg://"
                "...): one SQLite file is not shared by several processes; without --workers, one process runs on it"
            )
        self.run_dir = (self.settings.data_dir / "cluster").resolve()
        base = os.environ.get("GAITSCOPE_NODE") or socket.gethostname().split(".")[0]
        exe = [sys.executable, "-m", "gaitscope.server.cli"]
        for i in range(1, self.count + 1):
            name, port = f"{base}-{i}", _free_port()
            flags = ["--host", LOOPBACK, "--port", str(port), "--data-dir", str(self.settings.data_dir)]
            flags += ["--log-level", self.log_level]
            if i > 1 or not self.settings.leg_view:
                flags.append("--no-leg-view")
            else:
                flags += ["--viser-port", str(self.settings.viser_port)]
            if i > 1 or not self.settings.demo:
                flags.append("--no-demo")
            env = {
                **os.environ,
                "GAITSCOPE_CLUSTER": "true",
                "GAITSCOPE_NODE": name,
                "GAITSCOPE_NODE_ADDRESS": f"{LOOPBACK}:{port}",
                "GAITSCOPE_DATABASE_URL": self.settings.database_url,
            }
            self.nodes.append(_Child(name, [*exe, "serve", *flags], env, self.run_dir / f"{name}.log"))

    def address(self, node: _Child) -> str:
        return node.env["GAITSCOPE_NODE_ADDRESS"]

    def start(self) -> str:
        """Start the nodes and nginx; the URL, once nginx answers. Raises :class:`WorkersError` (all stopped)."""
        nginx = find_nginx()
        self.run_dir.mkdir(parents=True, exist_ok=True)
        try:
            for node in self.nodes:
                node.start()
            for node in self.nodes:
                self._wait(node, functools.partial(_answers, f"http://{self.address(node)}/api/health"))
                self.say(f"gaitscope: node {node.name} answers on {self.address(node)}")
            s = self.settings
            tls = (s.tls_cert, s.tls_key) if s.tls_cert is not None and s.tls_key is not None else None
            conf = nginx_config(
                [ProxyNode(n.name, self.address(n)) for n in self.nodes], f"{s.host}:{s.port}", self.run_dir,
                max(s.max_upload_mb, s.upload_chunk_kb // 1024 + 1), tls,
            )  # fmt: skip
            (self.run_dir / "nginx.conf").write_text(conf)
            command = nginx_command(nginx, self.run_dir)
            self.nginx = _Child("nginx", command, dict(os.environ), self.run_dir / "nginx.log")
            self.nginx.start()
            scheme = "https" if tls else "http"
            url = f"{scheme}://{s.host}:{s.port}/"
            host = LOOPBACK if s.host in ("0.0.0.0", "::") else s.host
            self._wait(self.nginx, functools.partial(_listens, host, s.port))
            return url
        except BaseException:
            self.stop()
            raise

    def _wait(self, child: _Child, probe: Callable[[], bool]) -> None:
        deadline = time.monotonic() + START_TIMEOUT_S
        while not probe():
            if child.proc is not None and child.proc.poll() is not None:
                raise WorkersError(f"{child.name} exited with {child.proc.returncode} at start (see {child.log_path})")
            if time.monotonic() > deadline:
                raise WorkersError(f"{child.name} did not answer in {START_TIMEOUT_S:g} s (see {child.log_path})")
            time.sleep(0.2)

    def watch(self, poll_s: float = 0.5) -> int:
        """Until stopped: restart a node that exits; stop all if nginx exits. The exit status."""
        while not self._stopping:
            if self.nginx is not None and self.nginx.proc is not None and self.nginx.proc.poll() is not None:
                self.say(f"gaitscope: nginx exited with {self.nginx.proc.returncode} (see {self.nginx.log_path}): "
                         "stopping the nodes")  # fmt: skip
                self.stop()
                return 1
            now = time.monotonic()
            for node in self.nodes:
                if node.proc is None or node.proc.poll() is None:
                    continue
                if node.next_start == 0.0:
                    node.next_start = now + node.pause_s
                    self.say(f"gaitscope: node {node.name} exited with {node.proc.returncode}; starting it again in "
                             f"{node.pause_s:g} s (see {node.log_path})")  # fmt: skip
                elif now >= node.next_start:
                    node.restarts += 1
                    node.pause_s = min(30.0, node.pause_s * 2)
                    node.next_start = 0.0
                    node.start()
            time.sleep(poll_s)
        return 0

    def stop(self) -> None:
        """nginx first (no new requests), then the nodes (each ends its sessions and recordings); idempotent."""
        self._stopping = True
        if self.nginx is not None:
            self.nginx.stop(signal.SIGQUIT)  # graceful: open connections finish
            self.nginx.wait(time.monotonic() + 5.0)
        for node in self.nodes:
            node.stop()
        deadline = time.monotonic() + STOP_TIMEOUT_S
        for node in self.nodes:
            node.wait(deadline)
        for child in [*self.nodes, *([self.nginx] if self.nginx else [])]:
            if child.log is not None:
                child.log.close()
                child.log = None


def run_workers(settings: Settings, count: int, log_level: str) -> int:
    """``serve --workers``: start, print the URL, supervise until SIGTERM/SIGINT; the exit status."""
    workers = Workers(settings, count, log_level)

    def _stop(signum: int, _frame: object) -> None:
        workers._stopping = True

    signal.signal(signal.SIGTERM, _stop)
    signal.signal(signal.SIGINT, _stop)
    url = workers.start()
    names = ", ".join(n.name for n in workers.nodes)
    print(f"gaitscope: serving on {url}  ({count} nodes behind nginx: {names}; API docs at /docs)", flush=True)
    status = workers.watch()
    workers.stop()
    return status
