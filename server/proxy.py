"""The nginx configuration in front of several gaitscope nodes (``gaitscope serve --workers N``).

nginx routes; gaitscope only answers its question. Every request to a session (its REST calls
``/api/sessions/{id}/...``, its browsers' ``/ws/sessions/{id}`` and its device's ``/ws/devices/{id}``) and every
creation of a session (``/api/sessions``) first asks a node, through nginx's ``auth_request``, which node
answers it (``GET /api/cluster/route``, :meth:`gaitscope.sessions.cluster.nodes.Nodes.route`): the node that
runs the session, or for a new one the least-loaded node. nginx maps the name it gets back to that node's
upstream and forwards the request there, websockets included. Everything else (the dashboard's files,
subjects, review, reports) goes to any node (least connections): they share the database and the data folder.
Uploads and report exports live in the memory of the node that began them until they finish, so their
requests go to one node per client (a consistent hash of the client's address and login cookie); so does
``/api/health``, whose ``instance`` the dashboard watches to tell a restarted server from a dropped network
(from alternating nodes it would see a restart every second).

A node name the configuration does not know (a node of another machine sharing the database) maps to "any
node", which refuses a session it does not run with the name of the node that does. The route question is
not reachable from outside (404): only nginx's internal subrequest asks it. Directives are from nginx's
documentation (``ngx_http_auth_request_module``, ``ngx_http_upstream_module``, ``ngx_http_map_module``).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Final

#: The internal location of the route question.
ROUTE_LOCATION: Final = "/_gaitscope_route"
_NAME: Final = re.compile(r"^[A-Za-z0-9_.:-]{1,128}$")


@dataclass(frozen=True)
class ProxyNode:
    """A node as nginx reaches it: its name (``GAITSCOPE_NODE``) and ``host:port``."""

    name: str
    address: str


def _quoted(value: str) -> str:
    if not _NAME.match(value):
        raise ValueError(f"node name or address {value!r}: only letters, digits and _ . : - (at most 128)")
    return f'"{value}"'


def nginx_config(
    nodes: Sequence[ProxyNode], listen: str, run_dir: Path, max_body_mb: int, tls: tuple[Path, Path] | None = None
) -> str:
    """The whole ``nginx.conf``: nginx in the foreground, its pid, logs and temporary files in ``run_dir``,
    listening on ``listen`` (``host:port``; HTTPS with ``tls`` = (certificate, key))."""
    if not nodes:
        raise ValueError("a proxy needs at least one node")
    names = [n.name for n in nodes]
    if len(set(names)) != len(names):
        raise ValueError(f"node names must differ: {names}")
    upstreams = "\n".join(
        f"    upstream gs_{i} {{ server {_quoted(n.address)[1:-1]}; keepalive 4; }}" for i, n in enumerate(nodes)
    )
    mapped = "\n".join(f"        {_quoted(n.name)} gs_{i};" for i, n in enumerate(nodes))
    servers = "\n".join(f"        server {n.address} max_fails=1 fail_timeout=2s;" for n in nodes)
    ssl = (
        f" ssl;\n        ssl_certificate {tls[0]};\n        ssl_certificate_key {tls[1]}"
        if tls is not None else ""
    )  # fmt: skip
    # proxy_set_header directives are inherited only by a level that sets none: the route location sets its own
    forwarded = """proxy_set_header Host $http_host;
            proxy_set_header X-Forwarded-For $proxy_add_x_forwarded_for;
            proxy_set_header X-Forwarded-Proto $scheme;"""
    return f"""# Written by `gaitscope serve --workers {len(nodes)}` (gaitscope/server/proxy.py) at every start.
worker_processes 1;
daemon off;
pid {run_dir}/nginx.pid;
error_log {run_dir}/nginx-error.log warn;
events {{ worker_connections 4096; }}
http {{
    access_log off;
    server_tokens off;
    client_body_temp_path {run_dir}/tmp-body;
    proxy_temp_path {run_dir}/tmp-proxy;
    fastcgi_temp_path {run_dir}/tmp-fastcgi;
    uwsgi_temp_path {run_dir}/tmp-uwsgi;
    scgi_temp_path {run_dir}/tmp-scgi;
    client_max_body_size {max_body_mb}m;
    proxy_request_buffering off;
    proxy_buffering off;
    tcp_nodelay on;
    proxy_http_version 1.1;
    proxy_read_timeout 1h;
    proxy_send_timeout 1h;
    map $http_upgrade $connection_upgrade {{
        default upgrade;
        "" "";
    }}
    map $gs_node $gs_upstream {{
        default gs_any;
{mapped}
    }}
    upstream gs_any {{
        least_conn;
{servers}
        keepalive 16;
    }}
    upstream gs_sticky {{
        hash "$remote_addr $cookie_gaitscope_login" consistent;
{servers}
        keepalive 16;
    }}
{upstreams}
    server {{
        listen {listen}{ssl};
        location = {ROUTE_LOCATION} {{
            internal;
            proxy_pass http://gs_any/api/cluster/route;
            proxy_pass_request_body off;
            proxy_set_header Content-Length "";
            proxy_set_header Upgrade "";
            proxy_set_header Connection "";
            proxy_set_header X-Forwarded-Method $request_method;
            proxy_set_header X-Forwarded-Uri $request_uri;
            {forwarded}
        }}
        location = /api/cluster/route {{
            return 404;
        }}
        location ~ ^/api/(health$|uploads|exports|sessions/[0-9]+/exports|trials/[0-9]+/exports) {{
            proxy_pass http://gs_sticky;
            proxy_set_header Upgrade "";
            proxy_set_header Connection "";
            {forwarded}
        }}
        location ~ ^/(api/sessions|ws/sessions/|ws/devices/) {{
            auth_request {ROUTE_LOCATION};
            auth_request_set $gs_node $upstream_http_x_gaitscope_node;
            proxy_pass http://$gs_upstream;
            proxy_set_header Upgrade $http_upgrade;
            proxy_set_header Connection $connection_upgrade;
            {forwarded}
        }}
        location / {{
            proxy_pass http://gs_any;
            proxy_set_header Upgrade $http_upgrade;
            proxy_set_header Connection $connection_upgrade;
            {forwarded}
        }}
    }}
}}
"""
