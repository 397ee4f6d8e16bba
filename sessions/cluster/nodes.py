"""Membership of the gaitscope processes sharing one database, and where each request goes.

A node (``Settings.node``) registers at start-up with the address the proxy reaches it at, then beats every
:data:`BEAT_S`. A node is *live* while its last beat is younger than the timeout (default
:data:`TIMEOUT_S`) and it has not been declared gone. Times are each node's UTC wall clock: nodes on several
machines need synchronised clocks (NTP), with an error well under the timeout.

Routing (:meth:`Nodes.route`), asked by the proxy for each request to a session (nginx's ``auth_request``,
Caddy's ``forward_auth``; ``server/routes/cluster.py``):

- a session's REST calls and websockets (``/api/sessions/{id}/...``, ``/ws/sessions/{id}``,
  ``/ws/devices/{id}``) go to the node that runs it, when that node is live;
- a new session (``POST /api/sessions``) and the start of a created one go to the least-loaded live node
  (fewest running sessions; ties to the first name), so that sessions spread over the nodes as they start;
- a session that runs on no live node (created, ended, or its node gone) to one live node chosen by its id
  (rendezvous hashing: the same node for every caller while the live nodes stay the same, so that what a
  node keeps in memory for it, like its summary's progress, is found again), which answers for itself
  (a session that ended says so);
- everything else to the least-loaded live node (the proxy does not ask for those: they go to any node).

Takeover (:meth:`Nodes.claim_gone`): a live node that finds another's beat older than the timeout marks it
``gone`` (one write transaction, so two survivors never both take the same node) and then recovers it as the
node itself would after a crash: its recordings re-indexed, its sessions stopped with an event saying why
(``SessionManager.recover_after_crash(node=...)``). The devices of those sessions, reconnecting through the
proxy, are told the session stopped. A node that beats again after being declared gone is *fenced*:
:meth:`Nodes.beat` says so and the node stops whatever it still runs before registering again, so one
session is never run by two nodes.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Final

from sqlalchemy import select

from gaitscope.sessions.cluster.tables import NodeRow
from gaitscope.sessions.store import NotFound, Store

#: Seconds between a node's beats.
BEAT_S: Final = 1.0
#: Seconds without a beat after which a node is gone (its sessions are taken over).
TIMEOUT_S: Final = 10.0

#: A request to one session: its REST calls and its two websockets.
_SESSION_PATH: Final = re.compile(r"^/(?:api/sessions|ws/sessions|ws/devices)/(\d{1,19})(/[^?]*)?(?:\?.*)?$")


@dataclass(frozen=True)
class Node:
    """A node as the proxy and the API see it: its name, its address, how many sessions it runs."""

    name: str
    address: str
    state: str
    seen_utc: str
    running: int
    live: bool


def _utc_now() -> dt.datetime:
    return dt.datetime.now(dt.UTC)


class Nodes:
    """This node's membership in the ``nodes`` table of ``store``, and the routing rule (module docstring).

    ``clock``: the UTC wall clock (injected by tests)."""

    def __init__(
        self,
        store: Store,
        name: str,
        address: str,
        timeout_s: float = TIMEOUT_S,
        clock: Callable[[], dt.datetime] = _utc_now,
    ):
        if timeout_s <= 2 * BEAT_S:
            raise ValueError(f"node timeout {timeout_s:g} s must exceed two beats ({2 * BEAT_S:g} s)")
        self.store = store
        self.name = name
        self.address = address
        self.timeout = dt.timedelta(seconds=timeout_s)
        self.clock = clock

    def _stamp(self) -> str:
        return self.clock().isoformat(timespec="milliseconds")

    def register(self) -> None:
        """This node is up, at its address, from now (a restart under the same name comes back here)."""
        now = self._stamp()
        with self.store.writing() as session:
            row = session.get(NodeRow, self.name, with_for_update=True)
            if row is None:
                session.add(NodeRow(name=self.name, address=self.address, state="up", started_utc=now, seen_utc=now))
            else:
                row.address, row.state, row.started_utc, row.seen_utc, row.gone_by = self.address, "up", now, now, None

    def beat(self) -> bool:
        """Stamp this node's beat; False when it has been declared gone (fenced: stop everything, then
        :meth:`register` again)."""
        with self.store.writing() as session:
            row = session.get(NodeRow, self.name, with_for_update=True)
            if row is None or row.state != "up":
                return False
            row.seen_utc = self._stamp()
            return True

    def gone_by(self) -> str | None:
        """The node that declared this one gone (after :meth:`beat` returned False), if it is known."""
        with self.store.reading() as session:
            row = session.get(NodeRow, self.name)
            return None if row is None else row.gone_by

    def claim_gone(self) -> list[str]:
        """Declare gone every other node whose beat is older than the timeout; their names (this node now
        owes them a recovery). One transaction: of two nodes that notice at once, one claims."""
        cutoff = self.clock() - self.timeout
        claimed = []
        with self.store.writing() as session:
            for row in session.scalars(select(NodeRow).where(NodeRow.state == "up").with_for_update()):
                if row.name != self.name and dt.datetime.fromisoformat(row.seen_utc) < cutoff:
                    row.state, row.gone_by = "gone", self.name
                    claimed.append(row.name)
        return claimed

    def nodes(self) -> list[Node]:
        """Every node known, by name, with its running sessions and whether it is live."""
        cutoff = self.clock() - self.timeout
        with self.store.reading() as session:
            rows = list(session.scalars(select(NodeRow).order_by(NodeRow.name)))
        counts = self.store.running_per_node()
        return [
            Node(r.name, r.address, r.state, r.seen_utc, counts.get(r.name, 0), self._live(r, cutoff)) for r in rows
        ]

    def _live(self, row: NodeRow, cutoff: dt.datetime) -> bool:
        return row.state == "up" and (row.name == self.name or dt.datetime.fromisoformat(row.seen_utc) >= cutoff)

    def _least_loaded(self, live: list[Node]) -> Node:
        return min(live, key=lambda n: (n.running, n.name))

    def route(self, method: str, uri: str) -> Node:
        """The node that should answer ``method uri`` (the rule in the module docstring)."""
        nodes = self.nodes()
        live = [n for n in nodes if n.live] or [Node(self.name, self.address, "up", self._stamp(), 0, True)]
        if (m := _SESSION_PATH.match(uri)) is not None:
            try:
                session = self.store.get_session(int(m.group(1)))
            except NotFound:  # any node says so; one chosen by the id, like a session that runs nowhere
                return _by_hash(live, int(m.group(1)))
            owner = next((n for n in live if n.name == session.node), None)
            if session.state == "running" and owner is not None:
                return owner
            if not (session.state == "created" and method == "POST" and (m.group(2) or "").rstrip("/") == "/start"):
                return _by_hash(live, session.id)
        return self._least_loaded(live)


def _by_hash(live: list[Node], session_id: int) -> Node:
    """The node a session that runs nowhere is served by (its summary's progress, the review): the same one for
    as long as the live nodes stay the same, whoever asks (rendezvous hashing)."""
    return max(live, key=lambda n: hashlib.sha256(f"{session_id}:{n.name}".encode()).digest())
