"""``/api/cluster``: where the proxy sends a request, and the nodes sharing this database (``sessions/cluster``).

``GET /api/cluster/route`` is the proxy's question before it forwards a request to a session (nginx's
``auth_request``, Caddy's ``forward_auth``): the request's method and URI come in ``X-Forwarded-Method`` and
``X-Forwarded-Uri``, the answer is ``204`` with the node's name in ``X-Gaitscope-Node`` (nginx maps it to an
upstream) and its address in ``X-Gaitscope-Upstream`` (Caddy proxies to it). It says nothing about a session
but which node runs it, so it needs no login; the proxies in ``docker/`` and ``server/cluster`` do not forward
it from outside. On a server that is not part of a cluster (``GAITSCOPE_CLUSTER`` off) it is 404.
"""

from __future__ import annotations

import asyncio
from typing import Annotated, Final

from fastapi import APIRouter, Header, HTTPException, Response

from gaitscope.server.auth import allow, public
from gaitscope.server.routes.common import Ctx
from gaitscope.sessions import schema
from gaitscope.sessions.cluster.nodes import Nodes

router = APIRouter(prefix="/api/cluster")

#: The longest request URI the route question accepts (nginx's default large header buffer is 8 KB).
MAX_URI: Final = 8192
_METHODS: Final = frozenset({"GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"})


def _nodes(c: Ctx) -> Nodes:
    if c.nodes is None:
        raise HTTPException(404, "this server is not part of a cluster (GAITSCOPE_CLUSTER is off)")
    return c.nodes


@router.get("/route", dependencies=[public()], status_code=204)
async def route(
    c: Ctx,
    response: Response,
    x_forwarded_method: Annotated[str, Header(max_length=16)] = "GET",
    x_forwarded_uri: Annotated[str, Header(max_length=MAX_URI)] = "/",
) -> None:
    """Which node answers ``X-Forwarded-Method X-Forwarded-Uri``: ``X-Gaitscope-Node``, ``X-Gaitscope-Upstream``."""
    nodes = _nodes(c)
    method = x_forwarded_method.upper()
    if method not in _METHODS or not x_forwarded_uri.startswith("/"):
        raise HTTPException(422, f"X-Forwarded-Method {method[:16]!r} and X-Forwarded-Uri must be a request")
    node = await asyncio.to_thread(nodes.route, method, x_forwarded_uri)
    response.headers["X-Gaitscope-Node"] = node.name
    response.headers["X-Gaitscope-Upstream"] = node.address
    response.headers["Cache-Control"] = "no-store"


@router.get("/nodes", dependencies=[allow("read")])
async def list_nodes(c: Ctx) -> list[schema.ClusterNode]:
    """Every node of the cluster, live or gone, with the sessions each runs."""
    nodes = _nodes(c)
    found = await asyncio.to_thread(nodes.nodes)
    return [
        schema.ClusterNode(
            name=n.name,
            address=n.address,
            state="gone" if n.state == "gone" else "up",
            seen_utc=n.seen_utc,
            running=n.running,
            live=n.live,
            this=n.name == nodes.name,
        )
        for n in found
    ]
