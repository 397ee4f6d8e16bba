"""The nginx configuration of ``serve --workers``: what it refuses, and that nginx itself accepts it."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from gaitscope.server.proxy import ProxyNode, nginx_config
from gaitscope.server.workers import WorkersError, find_nginx, nginx_command

NODES = [ProxyNode("gs-1", "127.0.0.1:8001"), ProxyNode("gs-2", "127.0.0.1:8002")]


def _nginx() -> str:
    try:
        return find_nginx()
    except WorkersError:
        pytest.skip("nginx is not installed (scripts/test.sh installs Debian's nginx)")


def test_nginx_accepts_the_configuration(tmp_path: Path) -> None:
    for tls in (None, (tmp_path / "cert.pem", tmp_path / "key.pem")):
        conf = nginx_config(NODES, "127.0.0.1:8000", tmp_path, 512, tls)
        (tmp_path / "nginx.conf").write_text(conf)
        if tls is not None:  # nginx -t loads the certificate: a real one
            subprocess.run(
                ["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-subj", "/CN=localhost", "-days", "1",
                 "-keyout", str(tls[1]), "-out", str(tls[0])], check=True, capture_output=True,
            )  # fmt: skip
        done = subprocess.run(nginx_command(_nginx(), tmp_path, "-t"), capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
    # a session's traffic asks the route first; the route question itself is not reachable from outside
    assert "auth_request /_gaitscope_route;" in conf
    assert "location = /api/cluster/route {\n            return 404;" in conf
    assert '"gs-2" gs_1;' in conf and "server 127.0.0.1:8002 max_fails=1" in conf


@pytest.mark.parametrize(
    ("nodes", "error"),
    [
        ([], "at least one node"),
        ([ProxyNode("a", "127.0.0.1:1"), ProxyNode("a", "127.0.0.1:2")], "must differ"),
        ([ProxyNode('a"; evil', "127.0.0.1:1")], "only letters"),
        ([ProxyNode("a", "127.0.0.1:1; include /etc/passwd")], "only letters"),
    ],
)
def test_names_that_would_break_the_configuration_are_refused(
    nodes: list[ProxyNode], error: str, tmp_path: Path
) -> None:
    with pytest.raises(ValueError, match=error):
        nginx_config(nodes, "127.0.0.1:8000", tmp_path, 512)


def test_the_route_question_is_not_asked_of_a_single_server(client: TestClient) -> None:
    r = client.get("/api/cluster/route", headers={"X-Forwarded-Uri": "/ws/devices/1"})
    assert r.status_code == 404 and "not part of a cluster" in r.json()["detail"]
    assert client.get("/api/cluster/nodes").status_code == 404
