"""Start ``gaitscope serve`` as a subprocess on a free port and wait until it answers.

Shared by the load benchmark and the tests that need a real server (crash recovery, slow clients, the
browser test): one place that knows how to start it, how to tell it is up, and how to stop it.
"""

from __future__ import annotations

import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO

LOOPBACK = "127.0.0.1"


#: Ports :func:`free_port` handed out in this process.
_HANDED_OUT: set[int] = set()


def free_port() -> int:
    """A TCP port on loopback that nothing listens on right now, never the same one twice in a process: the kernel
    may hand a port it just released out again, and a server given two ports (its own and the leg view's) from two
    calls then tried to bind one port twice ("address already in use", a CI failure)."""
    while True:
        with socket.socket() as s:
            s.bind((LOOPBACK, 0))
            port = int(s.getsockname()[1])
        if port not in _HANDED_OUT:
            _HANDED_OUT.add(port)
            return port


@dataclass
class RunningServer:
    proc: subprocess.Popen[bytes]
    port: int

    @property
    def base(self) -> str:
        return f"http://{LOOPBACK}:{self.port}"

    def stop(self) -> None:
        """Terminate (kill if it does not stop within 20 s) and reap the process."""
        self.proc.terminate()
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout=10)


def start_server(
    data_dir: Path | str,
    *flags: str,
    env: Mapping[str, str] | None = None,
    output: IO[bytes] | int = subprocess.DEVNULL,
    timeout: float = 90.0,
    port: int | None = None,
) -> RunningServer:
    """``gaitscope serve --port <port> --data-dir data_dir *flags``, returned once ``/api/health`` answers
    (``port``: a free one by default).

    Raises:
        RuntimeError: the process exited, or did not answer within ``timeout`` seconds (it is stopped).
    """
    port = port or free_port()
    exe = str(Path(sys.executable).with_name("gaitscope"))
    cmd = [exe, "serve", "--port", str(port), "--data-dir", str(data_dir), *flags]
    proc = subprocess.Popen(cmd, env=None if env is None else dict(env), stdout=output, stderr=subprocess.STDOUT)
    server = RunningServer(proc, port)
    deadline = time.monotonic() + timeout
    while True:
        if proc.poll() is not None:
            raise RuntimeError(f"gaitscope serve exited with {proc.returncode}")
        try:
            urllib.request.urlopen(f"{server.base}/api/health", timeout=1).close()
            return server
        except OSError:
            if time.monotonic() > deadline:
                server.stop()
                raise RuntimeError(f"gaitscope serve did not answer /api/health in {timeout:g} s") from None
            time.sleep(0.2)
