"""The channel mappings a lab saved, by rig (:mod:`gaitscope.sessions.mappings`)."""

from __future__ import annotations

import datetime as dt
from typing import Final

from sqlalchemy import select

from gaitscope.sessions import schema
from gaitscope.sessions.mappings.tables import MappingRow
from gaitscope.sessions.store import NotFound, Store

__all__ = ["MAX_MAPPING_CHARS", "SavedMappings"]

#: Longest mapping kept (characters of JSON), as :class:`~gaitscope.sessions.schema.ImportOptions` accepts.
MAX_MAPPING_CHARS: Final = 200_000


def _row(r: MappingRow) -> schema.SavedMapping:
    return schema.SavedMapping(rig=r.rig, kind=r.kind, mapping=r.mapping, actor=r.actor, updated_utc=r.updated_utc)  # type: ignore[arg-type]


class SavedMappings:
    """The ``channel_mappings`` table of ``store``."""

    def __init__(self, store: Store):
        self.store = store

    def get(self, rig: str) -> schema.SavedMapping | None:
        """The mapping saved for ``rig`` (None: none)."""
        with self.store.reading() as session:
            row = session.get(MappingRow, rig)
            return None if row is None else _row(row)

    def save(self, rig: str, kind: schema.MappingKind, mapping: str, actor: str) -> schema.SavedMapping:
        """Keep ``mapping`` for ``rig``, replacing the one saved before."""
        if not rig or len(rig) > 64:
            raise ValueError(f"a rig signature has 1 to 64 characters, got {len(rig)}")
        if len(mapping) > MAX_MAPPING_CHARS:
            raise ValueError(f"a mapping has at most {MAX_MAPPING_CHARS} characters, got {len(mapping)}")
        now = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
        with self.store.writing() as session:
            row = session.get(MappingRow, rig, with_for_update=True)
            if row is None:
                row = MappingRow(rig=rig, kind=kind, mapping=mapping, actor=actor, updated_utc=now)
                session.add(row)
            else:
                row.kind, row.mapping, row.actor, row.updated_utc = kind, mapping, actor, now
            session.flush()
            return _row(row)

    def list(self) -> list[schema.SavedMapping]:
        """Every saved mapping, newest first."""
        with self.store.reading() as session:
            rows = session.scalars(select(MappingRow).order_by(MappingRow.updated_utc.desc(), MappingRow.rig))
            return [_row(r) for r in rows]

    def delete(self, rig: str) -> None:
        """Forget the mapping of ``rig``.

        Raises:
            NotFound: none is saved for it.
        """
        with self.store.writing() as session:
            row = session.get(MappingRow, rig, with_for_update=True)
            if row is None:
                raise NotFound(f"no mapping is saved for rig {rig}")
            session.delete(row)
