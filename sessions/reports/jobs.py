"""Export jobs: a session's (or one trial's) PDF report or CSV of estimates, made in a worker thread while the
browser polls their progress (``GET /api/exports/{id}``) and then downloads the file.

One worker thread makes one export at a time (a report reads every recording of the session; two at
once would only slow each other and the live sessions). A thread, as the review's own reads
(``/api/trials/{id}/series``) are: reading a recording costs about 30-100 µs per sample (the mcap reader),
so a 30-minute session at 200 Hz takes tens of seconds, during which the job's progress is shown; moving
exports to the upload worker process would keep that work off this process's GIL entirely.

Files go to ``<data>/exports/``; the newest
:data:`KEEP` jobs are kept, older ones are forgotten with their files, and a restart forgets them all
(:meth:`ExportJobs.clear_leftovers`).
"""

from __future__ import annotations

import datetime as dt
import threading
import uuid
from collections import OrderedDict
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Final

from gaitscope.sessions import schema
from gaitscope.sessions.reports.estimates_csv import write_estimates_csv
from gaitscope.sessions.reports.pdf import render_pdf
from gaitscope.sessions.reports.summary import session_summary
from gaitscope.sessions.store import Store

__all__ = ["KEEP", "ExportJobs", "ExportNotReady"]

KEEP: Final = 20
_EXT: Final = {"pdf": "pdf", "csv": "csv"}


class ExportNotReady(LookupError):
    """The export's file is not there (still running, or failed)."""


class ExportJobs:
    """The export jobs of one app."""

    def __init__(self, store: Store, data_dir: Path, version: str):
        self.store = store
        self.data_dir = data_dir
        self.folder = data_dir / "exports"
        self.version = version
        self._jobs: OrderedDict[str, schema.ExportJob] = OrderedDict()
        self._lock = threading.Lock()
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="gaitscope-export")
        #: A session's summary kept by the app when it is up to date (None: none), which a session's PDF then
        #: typesets without reading the recordings again (set by the routes: ``server/routes/reports.py``).
        self.kept: Callable[[int], schema.SessionSummary | None] | None = None

    def clear_leftovers(self) -> None:
        """Delete the files of an earlier run's exports."""
        if self.folder.is_dir():
            for path in self.folder.iterdir():
                if path.is_file():
                    path.unlink(missing_ok=True)

    def shutdown(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)

    def start(self, session_id: int, kind: schema.ExportKind, trial_id: int | None = None) -> schema.ExportJob:
        """Queue an export of a session, or of one trial of it (they must exist: ``NotFound`` otherwise)."""
        from gaitscope.sessions.store import NotFound

        session = self.store.get_session(session_id)
        subject = self.store.get_subject(session.subject_id)
        if trial_id is not None and all(t.id != trial_id for t in self.store.list_trials(session_id)):
            raise NotFound(f"trial {trial_id} is not a trial of session {session_id}")
        part = "" if trial_id is None else f"_trial{trial_id}"
        job = schema.ExportJob(
            id=uuid.uuid4().hex,
            session_id=session_id,
            trial_id=trial_id,
            kind=kind,
            state="running",
            progress=0.0,
            step="waiting for the exports before it",
            filename=f"gaitscope_{subject.code}_session{session_id}{part}.{_EXT[kind]}",
        )
        with self._lock:
            self._jobs[job.id] = job
            while len(self._jobs) > KEEP:
                _, old = self._jobs.popitem(last=False)
                self._path(old).unlink(missing_ok=True)
        self._pool.submit(self._run, job.id)
        return job

    def get(self, job_id: str) -> schema.ExportJob:
        from gaitscope.sessions.store import NotFound

        with self._lock:
            job = self._jobs.get(job_id)
        if job is None:
            raise NotFound(f"export {job_id} does not exist (it was never started, or the server restarted)")
        return job

    def file(self, job_id: str) -> tuple[schema.ExportJob, Path]:
        """A finished export and its file."""
        job = self.get(job_id)
        if job.state != "done":
            raise ExportNotReady(
                f"export {job_id} is not ready: {job.error}"
                if job.state == "failed"
                else f"export {job_id} is still running"
            )
        return job, self._path(job)

    # --- private --------------------------------------------------------------------------------

    def _path(self, job: schema.ExportJob) -> Path:
        return self.folder / f"{job.id}.{_EXT[job.kind]}"

    def _update(self, job_id: str, **changes: object) -> None:
        with self._lock:
            job = self._jobs.get(job_id)
            if job is not None:
                self._jobs[job_id] = job.model_copy(update=changes)

    def _run(self, job_id: str) -> None:
        job = self.get(job_id)
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            if job.kind == "pdf":
                self._pdf(job)
            else:
                self._csv(job)
            self._update(job_id, state="done", progress=1.0, step="ready to download")
        except Exception as err:  # reported to the user: the job says what failed, the server goes on
            self._path(job).unlink(missing_ok=True)
            self._update(job_id, state="failed", step="failed", error=_describe(err))

    def _progress(self, job_id: str, lo: float, hi: float, step: str) -> Callable[[int, int], None]:
        def on(done: int, total: int) -> None:
            self._update(job_id, progress=round(lo + (hi - lo) * done / max(total, 1), 3), step=step)

        return on

    def _pdf(self, job: schema.ExportJob) -> None:
        summary = self.kept(job.session_id) if self.kept is not None and job.trial_id is None else None
        if summary is None:
            self._update(job.id, step="reading the recordings")
            summary, _ = session_summary(
                self.store,
                self.data_dir,
                job.session_id,
                trial_id=job.trial_id,
                on_progress=self._progress(job.id, 0.0, 0.7, "reading the recordings"),
            )
        self._update(job.id, progress=0.75, step="typesetting the report")
        now = dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
        self._path(job).write_bytes(render_pdf(summary, version=self.version, generated_utc=now))

    def _csv(self, job: schema.ExportJob) -> None:
        self._update(job.id, step="writing the estimates")
        trials = [
            (t, self.data_dir / t.path)
            for t in self.store.list_trials(job.session_id)
            if t.status not in ("recording", "damaged") and job.trial_id in (None, t.id)
        ]

        def on(fraction: float) -> None:
            self._update(job.id, progress=round(0.98 * fraction, 3), step="writing the estimates")

        write_estimates_csv(trials, self._path(job), on)


def _describe(err: BaseException) -> str:
    """An error in a user's words, without server paths."""
    if isinstance(err, OSError):
        return err.strerror or "the server could not write the file"
    text = str(err)
    return text.split(": ", 1)[1] if text.startswith("file /") and ": " in text else text
