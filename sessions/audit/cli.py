"""``gaitscope audit``: check the audit trail's chain, or export it as CSV, from the server's console.

``gaitscope audit verify`` walks the chain (:meth:`gaitscope.sessions.audit.AuditLog.verify`) and exits 0 with
"audit trail intact: N entries" (and the newest hash), or 1 with the first problem found; with ``--checkpoint
FILE`` it also proves that no entry up to the checkpoint was cut off or rewritten. ``gaitscope audit checkpoint
--out FILE`` writes the trail's head, signed with the audit key (:class:`sessions.schema.AuditCheckpoint`), for the
admin to keep away from the server. Both need the audit key (``GAITSCOPE_AUDIT_KEY`` or the data folder's
``audit.key``, :mod:`gaitscope.sessions.audit.key`); without it they exit 2.
``gaitscope audit export --out F.csv`` writes the entries (all, or those the filters keep) as CSV; the export is
itself written to the trail, as done by ``cli``. The database is the server's: ``GAITSCOPE_DATABASE_URL``, else
the SQLite file in ``--data-dir`` (default ``GAITSCOPE_DATA_DIR``); a SQLite file that does not exist is an
error (status 2), not a new empty trail that would verify.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from gaitscope.sessions.errors import DataFormatError

__all__ = ["EXIT_BROKEN", "register"]

#: Exit status of ``verify`` when the chain is broken (bad input exits 2, as every command).
EXIT_BROKEN = 1
_FILTERS = ("user", "action", "outcome", "target", "since", "until")


def _open(a: argparse.Namespace) -> Any:
    from sqlalchemy.engine import make_url

    from gaitscope.server.settings import Settings
    from gaitscope.sessions.audit import AuditLog
    from gaitscope.sessions.audit.key import key_file, settings_key
    from gaitscope.sessions.store import Store

    settings = Settings(**({"data_dir": a.data_dir} if a.data_dir is not None else {}))
    url = make_url(settings.database_url)
    if url.get_backend_name() == "sqlite" and url.database not in (None, "", ":memory:"):
        if not Path(url.database).is_file():
            raise DataFormatError("no database there: give the server's --data-dir", file=url.database)
    key = settings_key(settings, create=False)
    if key is None:
        raise DataFormatError(
            "no audit key: set GAITSCOPE_AUDIT_KEY as the server has it, or give the server's --data-dir",
            file=str(key_file(settings.data_dir)),
        )
    store = Store(settings.database_url)
    return store, AuditLog(store, key)


def cmd_audit(a: argparse.Namespace) -> int:
    from gaitscope.sessions import schema
    from gaitscope.sessions.audit.export import csv_chunks

    if a.audit_command == "export":
        try:
            query = schema.AuditQuery(**{f: getattr(a, f) for f in _FILTERS if getattr(a, f) is not None})
        except ValidationError as e:
            problems = "; ".join(f"--{'.'.join(str(x) for x in err['loc']) or 'since/until'}: {err['msg']}"
                                 for err in e.errors())  # fmt: skip
            raise DataFormatError(problems, file="audit export") from None
    store, audit = _open(a)
    try:
        if a.audit_command == "verify":
            result = audit.verify(checkpoint=None if a.checkpoint is None else _read_checkpoint(a.checkpoint))
            if not result.ok:
                print(f"audit trail BROKEN after {result.entries} good entries: {result.problem}")
                return EXIT_BROKEN
            print(f"audit trail intact: {result.entries} entries")
            if result.keyed_from is not None and result.keyed_from > 1:
                print(f"entries 1 to {result.keyed_from - 1} predate the audit key: checked by the SHA-256 chain only")
            if result.checkpoint_seq is not None:
                print(f"no entry up to seq {result.checkpoint_seq} (the checkpoint) was cut off or rewritten")
            if result.last_hash:
                print(f"newest hash: {result.last_hash}")
            return 0
        try:
            audit.ensure_keyed(user="cli")  # before writing: refused if the server writes with another key
        except ValueError as e:
            raise DataFormatError(str(e), file="audit") from None
        if a.audit_command == "checkpoint":
            audit.record(user="cli", role="admin", action="audit.checkpoint", target="audit", outcome="done")
            mark = audit.checkpoint()
            a.out.parent.mkdir(parents=True, exist_ok=True)
            a.out.write_text(mark.model_dump_json(indent=2) + "\n", encoding="utf-8")
            print(f"wrote the checkpoint of seq {mark.seq} (hash {mark.hash}) to {a.out}: keep it away from the server")
            return 0
        filters = query.model_dump(exclude_none=True, exclude={"limit", "offset"})
        audit.record(user="cli", role="admin", action="audit.export", target="audit", after=filters)
        out: Path = a.out
        out.parent.mkdir(parents=True, exist_ok=True)
        written = 0

        def counted() -> Iterator[schema.AuditEntry]:
            nonlocal written
            for entry in audit.iter(query):
                written += 1
                yield entry

        with out.open("w", encoding="utf-8", newline="") as f:  # newline="": the csv module writes CRLF itself
            for piece in csv_chunks(counted()):
                f.write(piece)
        print(f"wrote {written} entries to {out}")
        return 0
    finally:
        store.close()


def _read_checkpoint(path: Path) -> Any:
    from gaitscope.sessions import schema

    try:
        return schema.AuditCheckpoint.model_validate_json(path.read_bytes())
    except OSError as e:
        raise DataFormatError(f"cannot read the checkpoint: {e.strerror}", file=str(path)) from None
    except ValidationError as e:
        problems = "; ".join(f"{'.'.join(str(x) for x in err['loc'])}: {err['msg']}" for err in e.errors())
        raise DataFormatError(f"not an audit checkpoint: {problems}", file=str(path)) from None


def register(sub: Any) -> None:
    """Add ``gaitscope audit`` to the command line's subcommands."""
    from gaitscope.sessions import schema

    p = sub.add_parser("audit", help="the audit trail: verify its chain, write a checkpoint, export it as CSV")
    p.add_argument("--data-dir", type=Path, help="the server's data folder (default GAITSCOPE_DATA_DIR)")
    cmds = p.add_subparsers(dest="audit_command", required=True)
    q = cmds.add_parser("verify", help="check the chain: exit 0 if intact, 1 at the first changed or missing entry")
    q.add_argument("--data-dir", type=Path, default=argparse.SUPPRESS, help="as above, after the command")
    q.add_argument("--checkpoint", type=Path, help="a checkpoint file: also prove no entry up to it was cut off")
    q = cmds.add_parser("checkpoint", help="write the trail's head, signed with the audit key, to keep elsewhere")
    q.add_argument("--data-dir", type=Path, default=argparse.SUPPRESS, help="as above, after the command")
    q.add_argument("--out", type=Path, required=True, help="the checkpoint file to write (JSON)")
    q = cmds.add_parser("export", help="write the entries as CSV (all, or those the filters keep)")
    q.add_argument("--data-dir", type=Path, default=argparse.SUPPRESS, help="as above, after the command")
    q.add_argument("--out", type=Path, required=True, help="the CSV file to write")
    q.add_argument("--user", help="only this user's entries")
    q.add_argument("--action", help="only actions starting so (e.g. 'settings.', 'refused')")
    q.add_argument("--outcome", choices=schema.AUDIT_OUTCOMES)
    q.add_argument("--target", help="only targets starting so")
    q.add_argument("--since", help="from this time on (ISO-8601; UTC if no zone)")
    q.add_argument("--until", help="before this time")
    p.set_defaults(func=cmd_audit)
