"""Chunked uploads of logs for review (``/api/uploads``): create, PUT chunks in order, finish or cancel.

An open upload lives in memory (:class:`Uploads`) and on disk as ``<data>/uploads/<id>.part``; a
restart ends every upload (:meth:`Uploads.clear_leftovers`). The rules:

- **One chunk at a time.** Each upload has an ``asyncio.Lock``: a request that finds a chunk still
  arriving (a second PUT, a finish) gets 409. A cancel is always accepted; a chunk still arriving for
  a cancelled upload is thrown away (404). A chunk is written at its offset, so a failed write never
  leaves stray bytes behind.
- **Quotas.** At most ``max_open_uploads`` are open at once (429); one without a request for
  ``upload_idle_s`` is dropped. A new upload is refused with 507 when the data folder's free space,
  less the bytes that open uploads and running imports may still write, would fall below
  ``upload_min_free_mb``; a chunk or an import that meets a full disk is 507 too.
- **Finish.** The import (:func:`gaitscope.sessions.formats.imports.run_import`) runs in one worker process, started on
  the first finish ('forkserver' where the platform has it, else 'spawn'; never 'fork' from a server
  with threads) and shut down with the app, so parsing and estimating a large file never holds this
  process's GIL while live sessions answer their devices. The worker writes the recording to
  ``uploads/<id>.import.mcap`` and returns counts; here the session and trial rows are created in one
  transaction that moves the recording into ``recordings/`` before it commits
  (:meth:`~gaitscope.sessions.store.Store.create_upload_trial`): both appear or neither does. A finished upload
  is gone whatever the outcome (a later request is 404). An MCAP recording that was never finished is
  refused as recoverable (header ``X-Gaitscope-Recoverable``); sent again and finished with
  ``recover=true``, it is re-indexed first, as start-up recovery does for the server's own recordings.
- **Once.** A file whose content (SHA-256, kept with its session's source) was uploaded before is refused
  with 409, naming the trial it is (header ``X-Gaitscope-Duplicate-Of``: its id); sent again and finished
  with ``keep_copy=true``, it is stored as another trial.
- Every message names the user's file, never a server path.
"""

from __future__ import annotations

import asyncio
import errno
import functools
import hashlib
import multiprocessing
import os
import re
import shutil
import time
import uuid
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Final

from fastapi import APIRouter, HTTPException, Query, Request, Response
from fastapi import Path as Path_

from gaitscope.server.auth import Uploader, allow
from gaitscope.server.routes.common import Ctx, audited
from gaitscope.server.settings import Settings
from gaitscope.sessions import schema
from gaitscope.sessions.formats.imports import ImportJob, ImportRefused, ImportResult, run_import

if TYPE_CHECKING:
    from gaitscope.server.app import AppContext

__all__ = ["DUPLICATE_HEADER", "RECOVERABLE", "RECOVERABLE_HEADER", "UploadState", "Uploads", "router"]

router = APIRouter(prefix="/api")

_MIB: Final = 1024 * 1024
#: How :func:`gaitscope.sessions.formats.mcap_io.check_mcap` ends the message for an unfinished recording.
RECOVERABLE: Final = "gaitscope can recover it"
#: Set (to "1") on the 422 refusing a recording that can be recovered: the browser offers the recovery.
RECOVERABLE_HEADER: Final = "X-Gaitscope-Recoverable"
#: Set (to the trial's id) on the 409 refusing a file uploaded before: the browser links that trial.
DUPLICATE_HEADER: Final = "X-Gaitscope-Duplicate-Of"
_DISK_FULL: Final = (errno.ENOSPC, errno.EDQUOT)


@dataclass
class UploadState:
    """One open upload.

    Attributes:
        info: what the client announced and how much has arrived.
        subject_id: whose log it is.
        path: where its bytes go (``<data>/uploads/<id>.part``).
        touched: ``time.monotonic()`` of its last request (idle uploads are dropped).
        lock: held while a chunk is received.
        closed: finished or cancelled; a chunk still arriving is thrown away.
    """

    info: schema.Upload
    subject_id: int
    path: Path
    touched: float
    lock: asyncio.Lock = field(default_factory=asyncio.Lock)
    closed: bool = False


class Uploads:
    """The open uploads of one app, their quotas, and the import worker process.

    Every method runs on the event loop (the routes are ``async``), so no two change it at once.

    Attributes:
        open: the open uploads by id.
        start_method: how the worker process is started (``forkserver`` or ``spawn``).
    """

    def __init__(self, settings: Settings):
        self.settings = settings
        self.folder = settings.data_dir / "uploads"
        self.open: dict[str, UploadState] = {}
        self.start_method = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
        self._importing: dict[str, int] = {}  # id -> bytes, of the imports running
        self._worker: ProcessPoolExecutor | None = None

    @property
    def worker_started(self) -> bool:
        """True once an import has started the worker process, until :meth:`shutdown`."""
        return self._worker is not None

    def clear_leftovers(self) -> None:
        """Delete what an earlier run left in the uploads folder (nothing there outlives a run)."""
        if self.folder.is_dir():
            for path in self.folder.iterdir():
                if not path.is_dir():
                    path.unlink(missing_ok=True)

    def shutdown(self) -> None:
        """Stop the worker process (an import in progress is waited for; queued ones are cancelled)."""
        if self._worker is not None:
            self._worker.shutdown(wait=True, cancel_futures=True)
            self._worker = None

    # --- the protocol ---------------------------------------------------------------------------

    def create(self, body: schema.UploadCreate) -> schema.Upload:
        """Open an upload after the size, count and disk-space checks (413, 429, 507)."""
        s = self.settings
        if body.size > s.max_upload_mb * _MIB:
            size = f"{body.size / _MIB:.1f} MiB"
            raise HTTPException(413, f"{body.filename} is {size}; the limit is {s.max_upload_mb} MiB")
        self._expire_idle()
        if len(self.open) >= s.max_open_uploads:
            raise HTTPException(
                429,
                f"{len(self.open)} uploads are open, the most allowed at once; finish or cancel one "
                f"(an upload without a request for {s.upload_idle_s:g} s is dropped)",
            )
        self._check_space(body)
        upload_id = uuid.uuid4().hex
        path = self.folder / f"{upload_id}.part"
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            path.touch(exist_ok=False)
        except OSError as err:
            raise _disk_error(err, body.filename) from None
        info = schema.Upload(
            id=upload_id, filename=body.filename, size=body.size, received=0, chunk_size=s.upload_chunk_kb * 1024
        )
        self.open[upload_id] = UploadState(info, body.subject_id, path, time.monotonic())
        return info

    async def receive(self, upload_id: str, offset: int, request: Request) -> schema.Upload:
        """Write the chunk at ``offset`` (409 out of order or while another arrives, 413 too long)."""
        state = self._get(upload_id)
        info = state.info
        if state.lock.locked():
            raise HTTPException(409, f"a chunk of {info.filename} is being received; send one chunk at a time")
        async with state.lock:
            state.touched = time.monotonic()
            if offset != info.received:
                raise HTTPException(409, f"expected the chunk at offset {info.received}, got {offset}")
            data = bytearray()
            async for part in request.stream():
                data += part
                if len(data) > info.chunk_size:
                    raise HTTPException(413, f"a chunk may hold at most {info.chunk_size} bytes")
            if info.received + len(data) > info.size:
                raise HTTPException(413, f"{info.filename}: more bytes than the {info.size} announced")
            try:
                if state.closed:
                    raise _gone(upload_id)
                await asyncio.to_thread(_write_at, state.path, offset, bytes(data))
            except OSError as err:
                raise _gone(upload_id) if state.closed else _disk_error(err, info.filename) from None
            if state.closed:  # cancelled while the chunk was written: throw it away
                state.path.unlink(missing_ok=True)
                raise _gone(upload_id)
            state.info = info.model_copy(update={"received": info.received + len(data)})
            state.touched = time.monotonic()
            return state.info

    def _complete(self, upload_id: str) -> UploadState:
        """The upload, all of it received and no chunk arriving (else 409)."""
        state = self._get(upload_id)
        info = state.info
        if state.lock.locked():
            raise HTTPException(409, f"a chunk of {info.filename} is still being received; finish after it")
        if info.received != info.size:
            raise HTTPException(409, f"received {info.received} of {info.size} bytes; send the rest first")
        return state

    async def _mapping(
        self, state: UploadState, c: AppContext, options: schema.ImportOptions
    ) -> tuple[str | None, bool]:
        """The mapping to read the upload with: the one given, else the one saved for the file's rig (then
        True), else None (the reader's suggestion)."""
        if options.mapping is not None:
            return options.mapping, False
        rig = await asyncio.to_thread(_rig, state.path, state.info.filename)
        saved = None if rig is None else c.mappings.get(rig)
        return (None, False) if saved is None else (saved.mapping, True)

    async def preview(self, upload_id: str, c: AppContext, options: schema.ImportOptions) -> schema.ImportPreview:
        """What an import of the upload would read (:mod:`gaitscope.sessions.formats.preview`); the upload stays
        open for its finish (or another preview with another mapping)."""
        from gaitscope.sessions.formats.preview import run_preview

        state = self._complete(upload_id)
        async with state.lock:
            state.touched = time.monotonic()
            mapping, saved = await self._mapping(state, c, options)
            subject = c.store.get_subject(state.subject_id)
            model = c.models.get("default")[0]
            scratch = self.folder / f"{upload_id}.preview.mcap"  # never written: a preview stores nothing
            job = ImportJob(state.path, state.info.filename, scratch, subject, model, mapping, options.allow_other_rig)
            try:
                preview = await asyncio.wrap_future(self._executor().submit(run_preview, job))
            except ImportRefused as err:
                raise HTTPException(422, str(err)) from None
            except BrokenProcessPool:
                self._worker = None
                raise HTTPException(503, f"the preview of {state.info.filename} stopped unexpectedly") from None
            state.touched = time.monotonic()
        return preview.model_copy(update={"mapping_source": "saved"}) if saved else preview

    async def finish(
        self,
        upload_id: str,
        c: AppContext,
        *,
        recover: bool = False,
        keep_copy: bool = False,
        options: schema.ImportOptions | None = None,
        actor: str = "local",
    ) -> schema.ImportedTrial:
        """Import a complete upload as a new session with one trial (422 for a bad file; 409 for a file uploaded
        before, unless ``keep_copy``: see :meth:`_once`).

        An MCAP recording that was never finished (cut off by a crash or a full disk) is refused with a
        422 that says it can be recovered and carries the header :data:`RECOVERABLE_HEADER`; sent again
        and finished with ``recover=True``, it is re-indexed first (:func:`gaitscope.sessions.formats.mcap_io.recover`,
        the crash recovery of the server's own recordings), then imported.
        """
        state = self._complete(upload_id)
        info = state.info
        options = options or schema.ImportOptions()
        self._close(upload_id)
        self._importing[upload_id] = info.size
        recording = self.folder / f"{upload_id}.import.mcap"
        try:
            digest = await self._once(state.path, info.filename, c, keep_copy)
            if info.filename.lower().endswith(".mcap"):
                await _unfinished_mcap(state.path, info.filename, recover)
            subject = c.store.get_subject(state.subject_id)
            model = c.models.get("default")[0]
            mapping, _ = await self._mapping(state, c, options)
            job = ImportJob(state.path, info.filename, recording, subject, model, mapping, options.allow_other_rig)
            result = await self._run(job)
            rel = f"recordings/upload_{int(time.time() * 1000)}_{upload_id[:8]}_{_safe_stem(info.filename)}.mcap"
            final = c.settings.data_dir / rel
            final.parent.mkdir(parents=True, exist_ok=True)
            try:  # synchronous: a cancelled request must not leave a commit running in a thread
                trial = c.store.create_upload_trial(
                    subject.id,
                    info.filename,
                    rel,
                    result.samples,
                    result.duration_s,
                    before_commit=functools.partial(os.replace, recording, final),
                    sha256=digest,
                )
            except BaseException:
                final.unlink(missing_ok=True)  # moved, then the commit failed: no rows, so no file
                raise
            if result.mapping is not None:  # the rig's next file maps itself
                text, kind, rig = result.mapping
                c.mappings.save(rig, kind, text, actor=actor)
            return schema.ImportedTrial(**trial.model_dump(), report=result.report)
        finally:
            del self._importing[upload_id]
            state.path.unlink(missing_ok=True)
            recording.unlink(missing_ok=True)

    @staticmethod
    async def _once(path: Path, filename: str, c: AppContext, keep_copy: bool) -> str:
        """The file's SHA-256 (of the bytes as sent); 409 naming the trial it was uploaded as already, unless
        ``keep_copy``. Two copies finished at the same moment may both pass: a second copy is harmless."""
        digest = await asyncio.to_thread(_sha256, path)
        earlier = None if keep_copy else await asyncio.to_thread(c.store.find_upload, digest)
        if earlier is not None:
            when = earlier.started_utc[:16].replace("T", " ")
            raise HTTPException(
                409,
                f"{filename} was uploaded already, as trial {earlier.id} ({earlier.name}, {when} "
                "UTC): nothing was stored; to keep a second copy anyway, send it again with keep_copy",
                headers={DUPLICATE_HEADER: str(earlier.id)},
            )
        return digest

    def cancel(self, upload_id: str) -> None:
        """Drop an upload and its bytes (a chunk still arriving is thrown away)."""
        self._get(upload_id)
        self._close(upload_id).path.unlink(missing_ok=True)

    # --- private --------------------------------------------------------------------------------

    def _get(self, upload_id: str) -> UploadState:
        state = self.open.get(upload_id)
        if state is None:
            raise _gone(upload_id)
        return state

    def _close(self, upload_id: str) -> UploadState:
        state = self.open.pop(upload_id)
        state.closed = True
        return state

    def _expire_idle(self) -> None:
        limit = time.monotonic() - self.settings.upload_idle_s
        for upload_id, state in list(self.open.items()):
            if state.touched < limit and not state.lock.locked():
                self._close(upload_id).path.unlink(missing_ok=True)

    def _check_space(self, body: schema.UploadCreate) -> None:
        """507 unless ``upload_min_free_mb`` stays free once every open upload and import is written.

        A running import counts its upload's size again: about what its recording will take.
        """
        pending = body.size + sum(s.info.size - s.info.received for s in self.open.values())
        pending += sum(self._importing.values())
        try:
            free = shutil.disk_usage(self.settings.data_dir).free
        except OSError:
            free = 0
        if free - pending < self.settings.upload_min_free_mb * _MIB:
            raise HTTPException(
                507,
                f"not enough free disk space on the server for {body.filename} ({body.size / _MIB:.1f} MiB); "
                "try again when other uploads have finished, or ask for space to be freed",
            )

    def _executor(self) -> ProcessPoolExecutor:
        if self._worker is None:
            context = multiprocessing.get_context(self.start_method)
            if self.start_method == "forkserver":
                # each worker starts with it imported
                context.set_forkserver_preload(["gaitscope.sessions.formats.imports"])
            self._worker = ProcessPoolExecutor(max_workers=1, mp_context=context)
        return self._worker

    async def _run(self, job: ImportJob) -> ImportResult:
        """``run_import(job)`` in the worker process, with its failures as HTTP errors."""
        future = self._executor().submit(run_import, job)
        try:
            return await asyncio.wrap_future(future)
        except asyncio.CancelledError:  # the worker cannot be interrupted: clean up after it
            future.add_done_callback(lambda _: job.target.unlink(missing_ok=True))
            raise
        except ImportRefused as err:
            raise HTTPException(422, str(err)) from None
        except BrokenProcessPool:
            self._worker = None  # the next import starts a new one
            raise HTTPException(
                503, f"the import of {job.filename} stopped unexpectedly (out of memory?); nothing was stored"
            ) from None
        except OSError as err:
            raise _disk_error(err, job.filename) from None


def _rig(path: Path, filename: str) -> str | None:
    """The rig signature of an upload that needs a channel mapping (another tool's MCAP recording, a C3D
    file), else None (as for a file that cannot be read: the import says why)."""
    from gaitscope.sessions.errors import DataFormatError

    suffix = Path(filename).suffix.lower()
    try:
        if suffix == ".mcap":
            from gaitscope.sessions.formats import foreign_mcap
            from gaitscope.sessions.formats.imports import foreign

            return foreign_mcap.rig_signature(path, filename) if foreign(path, filename) else None
        if suffix == ".c3d":
            from gaitscope.sessions.formats import c3d

            return c3d.rig_of(c3d.inspect_c3d(path, filename))
    except (DataFormatError, OSError, ValueError):
        return None
    return None


async def _unfinished_mcap(path: Path, name: str, recover: bool) -> None:
    """Refuse an MCAP recording that was never finished (422, recoverable), or recover it when asked."""
    from gaitscope.sessions.errors import DataFormatError
    from gaitscope.sessions.formats.mcap_io import check_mcap
    from gaitscope.sessions.formats.mcap_io import recover as recover_mcap

    try:
        await asyncio.to_thread(check_mcap, path, name=name)
        return
    except DataFormatError as err:
        if RECOVERABLE not in str(err):
            return  # any other problem: the import says it, in its words
    if not recover:
        raise HTTPException(
            422,
            f"file {name}: the MCAP file is incomplete (its recording was never finished: cut off by a crash, a "
            "full disk or the device stopping); gaitscope can recover what was recorded up to where it stops",
            headers={RECOVERABLE_HEADER: "1"},
        )
    try:
        await asyncio.to_thread(recover_mcap, path)
    except DataFormatError:
        raise HTTPException(422, f"file {name}: the recording could not be recovered (damaged beyond repair)") from None
    except OSError as err:
        raise _disk_error(err, name) from None


def _gone(upload_id: str) -> HTTPException:
    return HTTPException(404, f"upload {upload_id} does not exist (finished, cancelled, expired or never started)")


def _disk_error(err: OSError, filename: str) -> Exception:
    """507 for a full disk, naming the user's file; any other OSError as it is (a server fault)."""
    if err.errno in _DISK_FULL:
        return HTTPException(507, f"the server's disk is full; {filename} was not stored")
    return err


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        while block := f.read(1 << 20):
            h.update(block)
    return h.hexdigest()


def _write_at(path: Path, offset: int, data: bytes) -> None:
    """Write ``data`` at ``offset`` and cut the file there: what an earlier failed write left goes."""
    with path.open("r+b") as f:
        f.seek(offset)
        f.write(data)
        f.truncate()


def _safe_stem(filename: str) -> str:
    """The file name's stem as a harmless part of a server file name."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(filename).stem)[:40].strip("._") or "upload"


# --- routes --------------------------------------------------------------------------------------


@router.post("/uploads", status_code=201)
async def create_upload(body: schema.UploadCreate, c: Ctx, who: Uploader) -> schema.Upload:
    c.store.get_subject(body.subject_id)
    await audited(c, who, "upload.create", f"subject {body.subject_id}", after=body.model_dump())
    return c.uploads.create(body)


# The body is the chunk's raw bytes (read from the request stream, so FastAPI cannot see it): stated for the
# OpenAPI document, and so for the browser's generated client (web/api_client.js).
_RAW_BODY: Final = {
    "requestBody": {
        "required": True,
        "content": {"application/octet-stream": {"schema": {"type": "string", "format": "binary"}}},
    }
}


@router.put("/uploads/{upload_id}", dependencies=[allow("upload")], openapi_extra=_RAW_BODY)
async def upload_chunk(
    upload_id: str, request: Request, c: Ctx, offset: Annotated[int, Query(ge=0, le=schema.INT64_MAX)]
) -> schema.Upload:
    return await c.uploads.receive(upload_id, offset, request)


@router.post("/uploads/{upload_id}/preview")
async def preview_upload(
    upload_id: str, c: Ctx, who: Uploader, options: schema.ImportOptions | None = None
) -> schema.ImportPreview:
    """What an import of the (complete) upload would read, from its first seconds: the channels, a small plot of
    each, what they feed, what looks wrong, and the channel mapping in use for a file that needs one (given,
    saved for the file's rig, or suggested). Nothing is stored; the upload stays open."""
    return await c.uploads.preview(upload_id, c, options or schema.ImportOptions())


@router.post("/uploads/{upload_id}/finish", status_code=201)
async def finish_upload(
    upload_id: str,
    c: Ctx,
    who: Uploader,
    recover: bool = False,
    keep_copy: bool = False,
    options: schema.ImportOptions | None = None,
) -> schema.ImportedTrial:
    """Import the upload; ``recover=true`` first recovers an MCAP recording that was never finished;
    ``keep_copy=true`` stores a file uploaded before again (else 409, naming its trial). ``options``: the channel
    mapping of another tool's MCAP recording or of a C3D file (kept for the file's rig, so its next file maps
    itself); without it, the mapping saved for the rig, else the suggested one."""
    given = None if options is None else options.model_dump()
    after = {"recover": recover, "keep_copy": keep_copy, "options": given}
    await audited(c, who, "upload.finish", f"upload {upload_id[:64]}", after=after)
    return await c.uploads.finish(upload_id, c, recover=recover, keep_copy=keep_copy, options=options, actor=who.name)


@router.get("/mappings", dependencies=[allow("read")])
async def list_mappings(c: Ctx) -> list[schema.SavedMapping]:
    """The channel mappings saved per rig, newest first."""
    return await asyncio.to_thread(c.mappings.list)


@router.delete("/mappings/{rig}", status_code=204)
async def delete_mapping(
    rig: Annotated[str, Path_(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9-]+$")], c: Ctx, who: Uploader
) -> Response:
    """Forget the mapping saved for ``rig`` (its next file gets the suggested one again)."""
    from gaitscope.sessions.store import NotFound

    await audited(c, who, "mapping.delete", f"rig {rig}")
    try:
        await asyncio.to_thread(c.mappings.delete, rig)
    except NotFound as err:
        raise HTTPException(404, str(err)) from None
    return Response(status_code=204)


@router.delete("/uploads/{upload_id}", status_code=204)
async def cancel_upload(upload_id: str, c: Ctx, who: Uploader) -> Response:
    await audited(c, who, "upload.cancel", f"upload {upload_id[:64]}")
    c.uploads.cancel(upload_id)
    return Response(status_code=204)
