"""The table of saved channel mappings (on :data:`gaitscope.sessions.store.Base`; ``0007_channel_mappings``)."""

from __future__ import annotations

from sqlalchemy import String, Text
from sqlalchemy.orm import Mapped, mapped_column

from gaitscope.sessions.store import Base


class MappingRow(Base):
    """The mapping saved for one rig: its kind (``mcap``, ``c3d``), its JSON, who saved it last and when."""

    __tablename__ = "channel_mappings"

    rig: Mapped[str] = mapped_column(String(64), primary_key=True)
    kind: Mapped[str] = mapped_column(String(8))
    mapping: Mapped[str] = mapped_column(Text)
    actor: Mapped[str] = mapped_column(String(128))
    updated_utc: Mapped[str] = mapped_column(String(40))
