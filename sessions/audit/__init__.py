"""The audit trail (issue #13): an append-only, hash-chained table of who changed what, each entry MAC'd under a
key kept outside the database, its checkpoints and its check."""

from gaitscope.sessions.audit.key import audit_key
from gaitscope.sessions.audit.log import LOCK_KEY, AuditKeyMismatch, AuditLog, checkpoint_mac, entry_hash, entry_mac

__all__ = ["LOCK_KEY", "AuditKeyMismatch", "AuditLog", "audit_key", "checkpoint_mac", "entry_hash", "entry_mac"]
