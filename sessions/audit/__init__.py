"""The audit trail (issue #13): an append-only, hash-chained table of who changed what, each entry MAC'd under a
key kept outside the database, its checkpoints and its check."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from gaitscope.sessions.audit.key import audit_key
    from gaitscope.sessions.audit.log import (
        LOCK_KEY,
        AuditKeyMismatch,
        AuditLog,
        checkpoint_mac,
        entry_hash,
        entry_mac,
    )

#: Where each name lives: imported on first use (PEP 562), so that ``gaitscope.sessions.audit.cli``, which
#: every gaitscope command registers, does not import SQLAlchemy's tables with it.
_LAZY = {"audit_key": "gaitscope.sessions.audit.key"} | dict.fromkeys(
    ["LOCK_KEY", "AuditKeyMismatch", "AuditLog", "checkpoint_mac", "entry_hash", "entry_mac"],
    "gaitscope.sessions.audit.log",
)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'gaitscope.sessions.audit' has no attribute {name!r}")


__all__ = ["LOCK_KEY", "AuditKeyMismatch", "AuditLog", "audit_key", "checkpoint_mac", "entry_hash", "entry_mac"]
