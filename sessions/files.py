"""Atomic file output shared by every writer of gaitscope files."""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_output(path: Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on a clean exit move it over ``path``, else delete it.

    The temporary file is created empty (with the usual permissions), synced to disk before the move,
    and removed if the body or the move raises, so ``path`` is either untouched or completely new.
    """
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex}.tmp")
    tmp.open("xb").close()
    try:
        yield tmp
        with tmp.open("rb+") as written:
            os.fsync(written.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
