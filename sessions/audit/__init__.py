"""The audit trail (issue #13): an append-only, hash-chained table of who changed what, and its check."""

from sessions.audit.log import LOCK_KEY, AuditLog, entry_hash

__all__ = ["LOCK_KEY", "AuditLog", "entry_hash"]
