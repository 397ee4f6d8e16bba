"""``/api/sessions/{id}/summary`` and ``/api/exports``: a session's summary (kept, with the progress of its
making), and its PDF report and CSV of estimates, or a trial's, made as export jobs whose progress the browser
polls. Thin: logic in ``gaitscope.sessions.reports``.

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
from gaitscope.sessions.reports.summary import session_summary, with_events

router = APIRouter(prefix="/api")

_JobId = Annotated[str, Path(pattern=r"^[0-9a-f]{32}$", description="the export's id")]
_MEDIA = {"pdf": "application/pdf", "csv": "text/csv; charset=utf-8"}
#: Summaries kept (each a few hundred kB at most: curves of 51 points, one profile point per stride).
_CACHED = 8


class Summaries:
    """The summaries of one app: those kept (the newest :data:`_CACHED`, each with the state of its session's
    trials it was made of), those being made (one at a time per session, however many pages wait for it), and
    how far each of those has got (``GET /api/sessions/{id}/summary/progress``)."""

    def __init__(self) -> None:
        self.kept: OrderedDict[int, tuple[object, schema.SessionSummary]] = OrderedDict()
        self.making: dict[int, tuple[object, asyncio.Future[schema.SessionSummary]]] = {}
        self.progress: dict[int, tuple[int, int]] = {}

    @staticmethod
    def key(c: Ctx, session_id: int) -> object:
        """What a summary is made of, besides the events and settings that :func:`with_events` refreshes: the
        session's trials (a new one, one that grew or changed status) and whether it has stopped."""
        session = c.store.get_session(session_id)
        trials = tuple((t.id, t.status, t.samples, t.duration_s, t.path) for t in c.store.list_trials(session_id))
        return session.state, trials

    async def get(self, c: Ctx, session_id: int) -> schema.SessionSummary:
        """The session's summary: the one kept if its trials have not changed since, else a new one."""
        key = self.key(c, session_id)
        hit = self.kept.get(session_id)
        if hit is not None and hit[0] == key:
            self.kept.move_to_end(session_id)
            made = hit[1]
        else:
            making = self.making.get(session_id)
            if making is None or making[0] != key:
                making = (key, asyncio.ensure_future(self._make(c, session_id, key)))
                self.making[session_id] = making
            made = await asyncio.shield(making[1])
        return with_events(made, c.store.get_session(session_id), c.store.list_events(session_id))

    async def _make(self, c: Ctx, session_id: int, key: object) -> schema.SessionSummary:
        def on_progress(done: int, total: int) -> None:
            self.progress[session_id] = (done, total)

        self.progress[session_id] = (0, 0)
        try:
            made, _ = await asyncio.to_thread(
                session_summary, c.store, c.settings.data_dir, session_id, on_progress=on_progress
            )
        finally:
            self.progress.pop(session_id, None)
            if self.making.get(session_id, (None,))[0] == key:
                del self.making[session_id]
        self.kept[session_id] = (key, made)
        self.kept.move_to_end(session_id)
        while len(self.kept) > _CACHED:
            self.kept.popitem(last=False)
        return made

    def fresh(self, c: Ctx, session_id: int) -> schema.SessionSummary | None:
        """The kept summary of the session, if its trials have not changed since (with its events now), else
        None. Called from the export worker's thread too (it only reads the kept summaries)."""
        hit = self.kept.get(session_id)
        if hit is None or hit[0] != self.key(c, session_id):
            return None
        return with_events(hit[1], c.store.get_session(session_id), c.store.list_events(session_id))

    def state(self, c: Ctx, session_id: int) -> schema.SummaryProgress:
        """How far the making of the session's summary has got, or whether it is kept."""
        hit = self.kept.get(session_id)
        cached = hit is not None and hit[0] == self.key(c, session_id)
        running = session_id in self.making
        done, total = self.progress.get(session_id, (0, 0))
        if running:
            step = f"reading the recordings: {done} of {total} gait states" if total else "counting the gait states"
        else:
            step = "ready" if cached else "not started"
        fraction = 1.0 if cached and not running else (min(1.0, done / total) if total else 0.0)
        return schema.SummaryProgress(running=running, cached=cached, progress=round(fraction, 3), step=step)


def _summaries(request: Request) -> Summaries:
    found = getattr(request.app.state, "summaries", None)
    if not isinstance(found, Summaries):
        found = Summaries()
        request.app.state.summaries = found
    return found


def _exports(request: Request, c: Ctx) -> ExportJobs:
    jobs = getattr(request.app.state, "exports", None)
    if jobs is None or jobs.store is not c.store:
        jobs = ExportJobs(c.store, c.settings.data_dir, gaitscope_version())
        jobs.clear_leftovers()
        summaries = _summaries(request)
        jobs.kept = lambda session_id: summaries.fresh(c, session_id)  # a kept summary is not made again
        request.app.state.exports = jobs
    return jobs


@router.get("/sessions/{session_id}/summary", dependencies=[allow("read")])
async def summary(session_id: Id, request: Request, c: Ctx) -> schema.SessionSummary:
    """Duration (recorded, and the wall time), strides, speed and incline profile, settings history, per-condition
    stride curves, data health and events of a session (its trials still recording are left out).

    A summary is kept until its session's trials change (a new trial, one that grew or changed status, the
    session stopping): opening it again does not read the recordings again, and its events and settings are
    brought up to date without. The newest :data:`_CACHED` are kept; two requests for one session while it is
    being made share the making, whose progress ``GET .../summary/progress`` tells."""
    c.store.get_session(session_id)
    return await _summaries(request).get(c, session_id)


@router.get("/sessions/{session_id}/summary/progress", dependencies=[allow("read")])
def summary_progress(session_id: Id, request: Request, c: Ctx) -> schema.SummaryProgress:
    """How far the making of the session's summary has got (for the page waiting for it), or that it is ready."""
    c.store.get_session(session_id)
    return _summaries(request).state(c, session_id)


@router.post("/sessions/{session_id}/exports", status_code=202)
def start_export(session_id: Id, body: schema.ExportCreate, request: Request, c: Ctx, who: Runner) -> schema.ExportJob:
    audit(c, who, f"export.{body.kind}", f"session {session_id}")
    return _exports(request, c).start(session_id, body.kind)


@router.post("/trials/{trial_id}/exports", status_code=202)
def start_trial_export(
    trial_id: Id, body: schema.ExportCreate, request: Request, c: Ctx, who: Runner
) -> schema.ExportJob:
    """A PDF report or a CSV of the estimates of one trial (the review page links them)."""
    trial = c.store.get_trial(trial_id)
    audit(c, who, f"export.{body.kind}", f"trial {trial_id}")
    return _exports(request, c).start(trial.session_id, body.kind, trial_id)


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
