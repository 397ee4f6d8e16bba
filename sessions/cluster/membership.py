"""A node's beat, its takeover of gone nodes and its own fencing, as one loop of the server's event loop.

:func:`keep_membership` runs for the server's lifetime when ``Settings.cluster`` is on (``server/app.py``).
Each :data:`~gaitscope.sessions.cluster.nodes.BEAT_S` it stamps this node's beat (through the database
writer, so the loop never waits on the database), declares gone every node whose beat is older than the
timeout and recovers each as that node would after a crash, in a thread. A beat refused because another
node declared this one gone (this process stalled longer than the timeout: a paused VM, a saturated
machine) stops every session this process still runs, since another node has already ended them and
re-indexed their recordings, and then registers again.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable

from gaitscope.sessions.cluster.nodes import BEAT_S, Nodes
from gaitscope.sessions.live.manager import SessionManager
from gaitscope.sessions.store_writer import StoreWriter

log = logging.getLogger(__name__)


async def beat_once(nodes: Nodes, manager: SessionManager, writer: StoreWriter) -> list[str]:
    """One beat: stamp it (fenced: stop what runs here, register again), then take over gone nodes; their names."""
    if not await writer.run(nodes.beat, "node beat"):
        by = await writer.run(nodes.gone_by, "node fenced by")
        log.error("node %s was declared gone by %s (no beat for too long): stopping its sessions", nodes.name, by)
        for session_id in list(manager.runtimes):
            try:
                await manager.stop(session_id)
            except Exception:
                log.exception("session %d: stop after this node was declared gone failed", session_id)
        await writer.run(nodes.register, "node register")
    gone = await writer.run(nodes.claim_gone, "node takeover")
    for name in gone:
        log.warning("node %s stopped answering: stopping its sessions and recovering its recordings", name)
        for trial in await asyncio.to_thread(manager.recover_after_crash, name):
            log.warning("recording of trial %d (node %s) recovered", trial.id, name)
    return gone


async def keep_membership(
    nodes: Nodes,
    manager: SessionManager,
    writer: StoreWriter,
    beat_s: float = BEAT_S,
    sleep: Callable[[float], Awaitable[None]] = asyncio.sleep,
) -> None:
    """:func:`beat_once` every ``beat_s`` until cancelled; a failed beat is logged and tried again."""
    while True:
        try:
            await beat_once(nodes, manager, writer)
        except Exception:
            log.exception("node %s: beat failed; trying again in %g s", nodes.name, beat_s)
        await sleep(beat_s)
