"""``gaitscope serve`` on a port of the test's choosing (a restart keeps its port: the page reconnects to it),
accounts on, returned once it answers ``/api/health``. ``start_server`` (``gaitscope.server.bench.launch``)
picks a free port itself; the e2e suite's usual server (``conftest.py``) is that one."""

from __future__ import annotations

import subprocess
import sys
import urllib.request
from collections.abc import Mapping
from pathlib import Path
from typing import IO

import pytest

from gaitscope.server.bench.launch import RunningServer, free_port, start_server
from tests.e2e.accounts import AUTH_ENV
from tests.waiting import wait_until


def _answers(server: RunningServer) -> bool:
    assert server.proc.poll() is None, f"gaitscope serve exited with {server.proc.returncode}"
    try:
        urllib.request.urlopen(f"{server.base}/api/health", timeout=1).close()
    except OSError:
        return False
    return True


def serve(data: Path, port: int, log: IO[bytes], *flags: str, timeout: float = 90.0) -> RunningServer:
    """``gaitscope serve --port port --data-dir data *flags`` (its output to ``log``), once it answers; the
    test fails with the end of the log (``log.name``) if it exits or does not answer in ``timeout`` s."""
    exe = str(Path(sys.executable).with_name("gaitscope"))
    cmd = [exe, "serve", "--port", str(port), "--data-dir", str(data), *flags]
    server = RunningServer(subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=AUTH_ENV), port)
    try:
        wait_until(lambda: _answers(server), timeout, f"gaitscope serve on port {port} to answer /api/health")
    except AssertionError as e:
        server.stop()
        log.flush()
        pytest.fail(f"{e}:\n{Path(str(log.name)).read_text(errors='replace')[-3000:]}")
    return server


def start(data: Path, env: Mapping[str, str] = AUTH_ENV) -> RunningServer:
    """``gaitscope serve`` on free ports (its leg view's too) with the data folder ``data`` and the environment
    ``env`` (default: accounts on), its output in ``data/server.log``; the test fails with the end of that
    log if it does not start."""
    log_path = data / "server.log"
    with log_path.open("wb") as log:
        try:
            return start_server(data, "--viser-port", str(free_port()), env=env, output=log)
        except RuntimeError as e:
            pytest.fail(f"{e}:\n{log_path.read_text(errors='replace')[-3000:]}")
