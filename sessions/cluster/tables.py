"""The table of gaitscope processes (nodes) sharing one database: who is up, where the proxy reaches it.

Declared on :data:`gaitscope.sessions.store.Base` (one database, one chain of migrations: ``0006_nodes``).
"""

from __future__ import annotations

from sqlalchemy import String
from sqlalchemy.orm import Mapped, mapped_column

from gaitscope.sessions.store import Base


class NodeRow(Base):
    """One gaitscope process: its name (``Settings.node``), the address the proxy reaches it at, and its beat.

    ``state`` is ``up`` while it beats, ``gone`` once another node found its beat older than the timeout and
    took its sessions over (``gone_by`` names that node). A node that beats again after being declared gone
    has been fenced: it stops what it still runs (:mod:`gaitscope.sessions.cluster.membership`).
    """

    __tablename__ = "nodes"

    name: Mapped[str] = mapped_column(String(128), primary_key=True)
    address: Mapped[str] = mapped_column(String(256))
    state: Mapped[str] = mapped_column(String(8))
    started_utc: Mapped[str] = mapped_column(String(40))
    seen_utc: Mapped[str] = mapped_column(String(40))
    gone_by: Mapped[str | None] = mapped_column(String(128))
