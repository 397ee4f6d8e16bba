"""``/api/sessions/{id}/summary`` and ``/api/exports``: a session's summary, and its PDF report and CSV of
estimates made as export jobs whose progress the browser polls. Thin: logic in ``gaitscope.sessions.reports``.

The export jobs live on ``app.state.exports``, made on first use (:func:`_exports`).
"""

from __future__ import annotations

import asyncio
import re
from collections import OrderedDict
from typing import Annotated

from fastapi import APIRouter, HTTPException, Path, Request
from fastapi.responses import FileResponse

from gaitscope.server.auth import Reader, Runner, allow
from gaitscope.server.routes.common import Ctx, Id, audit
from gaitscope.sessions import schema
from gaitscope.sessions.formats.models import gaitscope_version
from gaitscope.sessions.reports.jobs import ExportJobs, ExportNotReady
from gaitscope.sessions.reports.summary import session_summary

router = APIRouter(prefix="/api")

_JobId = Annotated[str, Path(pattern=r"^[0-9a-f]{32}$", description="the export's id")]
_MEDIA = {"pdf": "application/pdf", "csv": "text/csv; charset=utf-8"}
#: Summaries kept (each a few hundred kB at most: curves of 51 points, one profile point per stride).
_CACHED = 8


def _exports(request: Request, c: Ctx) -> ExportJobs:
    jobs = getattr(request.app.state, "exports", None)
    if jobs is None or jobs.store is not c.store:
        jobs = ExportJobs(c.store, c.settings.data_dir, gaitscope_version())
        jobs.clear_leftovers()
        request.app.state.exports = jobs
    return jobs


@router.get("/sessions/{session_id}/summary", dependencies=[allow("read")])
async def summary(session_id: Id, request: Request, c: Ctx) -> schema.SessionSummary:
    """Duration, strides, speed and incline profile, settings history, per-condition stride curves, data
    health and events of a session (its trials still recording are left out).

    A summary is kept until its session changes (its state, trials or events), so opening it again does not
    read the recordings again; the newest :data:`_CACHED` are kept."""
    session = c.store.get_session(session_id)
    key = (
        session.model_dump_json(),
        tuple((t.id, t.status, t.samples) for t in c.store.list_trials(session_id)),
        len(c.store.list_events(session_id)),
    )
    cache: OrderedDict[int, tuple[object, schema.SessionSummary]] = (
        getattr(request.app.state, "summaries", None) or OrderedDict()
    )
    request.app.state.summaries = cache
    hit = cache.get(session_id)
    if hit is not None and hit[0] == key:
        cache.move_to_end(session_id)
        return hit[1]
    result, _ = await asyncio.to_thread(session_summary, c.store, c.settings.data_dir, session_id)
    cache[session_id] = (key, result)
    while len(cache) > _CACHED:
        cache.popitem(last=False)
    return result


@router.post("/sessions/{session_id}/exports", status_code=202)
def start_export(session_id: Id, body: schema.ExportCreate, request: Request, c: Ctx, who: Runner) -> schema.ExportJob:
    audit(c, who, f"export.{body.kind}", f"session {session_id}")
    return _exports(request, c).start(session_id, body.kind)


@router.get("/exports/{job_id}", dependencies=[allow("read")])
def get_export(job_id: _JobId, request: Request, c: Ctx) -> schema.ExportJob:
    return _exports(request, c).get(job_id)


@router.get("/exports/{job_id}/file")
def export_file(job_id: _JobId, request: Request, c: Ctx, who: Reader) -> FileResponse:
    try:
        job, path = _exports(request, c).file(job_id)
    except ExportNotReady as err:
        raise HTTPException(409, str(err)) from None
    audit(c, who, "export.download", f"session {job.session_id}", detail=job.filename)
    filename = re.sub(r"[^A-Za-z0-9_.-]", "_", job.filename)
    return FileResponse(path, media_type=_MEDIA[job.kind], filename=filename)
