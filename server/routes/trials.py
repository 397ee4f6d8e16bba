"""``/api/trials``: recorded and uploaded trials: their events, decimated series, speed-change intent, MCAP
download, recorded settings, the estimators a re-run can run, re-runs through them, A/B comparisons of
re-runs (``/compare``) and the notes added in review (``/annotations``)."""

from __future__ import annotations

import asyncio
import functools
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

from fastapi import APIRouter, Body, HTTPException, Query, Response
from fastapi import Path as PathParam
from fastapi.responses import FileResponse

from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.server.auth import Annotator, Reader, allow
from gaitscope.server.routes.common import Ctx, Id, OptionalId, audit, audited, by, reviewable_trial, trained_model
from gaitscope.sessions import schema
from gaitscope.sessions.store import NotAllowed

if TYPE_CHECKING:
    from gaitscope.server.app import AppContext

router = APIRouter(prefix="/api")

#: Session time bounds of a series (s): finite (FastAPI reads "nan", "inf" and "1e400" as floats) and
#: within about 30 years, so that ``t * 1e9`` is an integer nanosecond time.
_SeriesTime = Annotated[
    float | None, Query(allow_inf_nan=False, ge=-1e9, le=1e9, description="session time (s); none: unbounded")
]
_MaxPoints = Annotated[int, Query(ge=10, le=20000)]


@router.get("/trials", dependencies=[allow("read")])
def list_trials(c: Ctx, session_id: OptionalId = None) -> list[schema.Trial]:
    return [c.manager.shown_trial(t) for t in c.store.list_trials(session_id)]


@router.get("/trials/{trial_id}", dependencies=[allow("read")])
def get_trial(trial_id: Id, c: Ctx) -> schema.Trial:
    return c.manager.shown_trial(c.store.get_trial(trial_id))


@router.get("/trials/{trial_id}/events", dependencies=[allow("read")])
def trial_events(trial_id: Id, c: Ctx) -> list[schema.Event]:
    c.store.get_trial(trial_id)
    return c.store.trial_events(trial_id)


@router.get("/trials/{trial_id}/series", dependencies=[allow("read")])
async def trial_series(
    trial_id: Id, c: Ctx, t0: _SeriesTime = None, t1: _SeriesTime = None, max_points: _MaxPoints = 2000
) -> dict[str, list[Any]]:
    from gaitscope.sessions.formats.mcap_io import read_series

    _, path = reviewable_trial(c, trial_id)
    return await asyncio.to_thread(read_series, path, t0, t1, max_points)


@router.get("/trials/{trial_id}/intent", dependencies=[allow("read")])
async def trial_intent(
    trial_id: Id, c: Ctx, t0: _SeriesTime = None, t1: _SeriesTime = None, max_points: _MaxPoints = 2000
) -> schema.IntentSeries:
    """The speed-change intent over the trial (desired and actual speed, decimated as ``/series``) as its
    ``intent`` estimator recorded it, or the channels that estimator needs and the trial lacks."""
    from gaitscope.sessions.review.intent import intent_series

    _, path = reviewable_trial(c, trial_id)
    return await asyncio.to_thread(intent_series, path, t0, t1, max_points)


@router.get("/trials/{trial_id}/download")
def download(trial_id: Id, c: Ctx, who: Reader) -> FileResponse:
    trial, path = reviewable_trial(c, trial_id)
    audit(c, who, "trial.download", f"trial {trial_id}")
    return FileResponse(path, media_type="application/octet-stream", filename=f"gaitscope_trial{trial.id}.mcap")


@router.get("/trials/{trial_id}/settings", dependencies=[allow("read")])
async def trial_settings(trial_id: Id, c: Ctx) -> schema.SessionSettings:
    """The settings in force at the trial's first frame, as recorded (its changes are on ``/events``)."""
    from gaitscope.sessions.review.rerun import recorded_settings

    _, path = reviewable_trial(c, trial_id)
    return await asyncio.to_thread(recorded_settings, path)


@router.get("/trials/{trial_id}/estimators", dependencies=[allow("read")])
async def trial_estimators(trial_id: Id, c: Ctx) -> schema.RerunChoices:
    """Which estimators a re-run of the trial can run: its recorded stack and those its channels feed."""
    from gaitscope.sessions.review.rerun import rerun_choices

    trial, path = reviewable_trial(c, trial_id)
    return await asyncio.to_thread(rerun_choices, path, _fingerprint(c, trial, path, None))


@router.post("/trials/{trial_id}/rerun", dependencies=[allow("run")])
async def rerun(
    trial_id: Id,
    c: Ctx,
    body: Annotated[schema.RerunRequest | None, Body()] = None,
    t0: _SeriesTime = None,
    t1: _SeriesTime = None,
    max_points: _MaxPoints = 2000,
) -> dict[str, list[Any]]:
    """The trial's raw frames through the estimators again (series like ``/series``, plus each estimator's
    outputs as ``<name>.<output>`` columns): as recorded by default, or with the body's settings over the
    whole trial (what if), and the recorded stack or the body's ``estimators``; see ``RerunRequest``."""
    from gaitscope.sessions.review.rerun import rerun_series

    trial, path = reviewable_trial(c, trial_id)
    subject = c.store.get_subject(c.store.get_session(trial.session_id).subject_id)
    settings = None if body is None else body.settings
    estimators = None if body is None else body.estimators
    fingerprint = _fingerprint(c, trial, path, None if body is None else body.personalization_id)

    def model(name: str) -> TrainedModel:
        return trained_model(c, name)

    return await asyncio.to_thread(
        rerun_series,
        path,
        model,
        subject.leg_length_m,
        subject.mass_kg,
        settings,
        t0,
        t1,
        max_points,
        estimators,
        fingerprint,
    )


def _fingerprint(c: AppContext, trial: schema.Trial, path: Path, personalization_id: int | None) -> list[float] | None:
    """The fingerprint ``fp_ls`` re-runs with: the personalization asked for (it must be the trial's
    subject's; 422 if not), else the one the trial recorded, else the subject's active one, else none."""
    from gaitscope.sessions.review.rerun import recorded_fingerprint

    subject_id = c.store.get_session(trial.session_id).subject_id
    if personalization_id is None:
        recorded = recorded_fingerprint(path)
        if recorded is not None:
            return recorded
        active = c.store.active_personalization(subject_id, "default")
        return None if active is None else active.fingerprint
    p = c.store.get_personalization(personalization_id)
    if p.subject_id != subject_id:
        raise HTTPException(422, f"personalization {personalization_id} is not of trial {trial.id}'s subject")
    return p.fingerprint


@router.post("/trials/{trial_id}/compare", dependencies=[allow("run")])  # re-runs the trial: as /rerun
async def compare(
    trial_id: Id,
    c: Ctx,
    body: schema.CompareRequest,
    t0: _SeriesTime = None,
    t1: _SeriesTime = None,
    max_points: _MaxPoints = 2000,
) -> schema.Comparison:
    """Two or more named re-runs of the trial side by side (A/B): each one's torque and phase, its
    difference from the first, its mean stride and its figures (peak torque, mean phase rate, stride
    length; errors against the ground truth when the trial has one: a simulated session's walk)."""
    from gaitscope.sessions.review.compare import WindowTooLong, simulated_truth
    from gaitscope.sessions.review.compare import compare as compare_runs

    trial, path = reviewable_trial(c, trial_id)
    session = c.store.get_session(trial.session_id)
    subject = c.store.get_subject(session.subject_id)
    fingerprint = _fingerprint(c, trial, path, None)
    source = session.source

    def model(name: str) -> TrainedModel:
        return trained_model(c, name)

    def run() -> schema.Comparison:
        truth = simulated_truth(source, path) if isinstance(source, schema.SimulatedSource) else None
        return compare_runs(
            path, model, subject.leg_length_m, subject.mass_kg, body.runs, t0, t1, max_points, fingerprint, truth
        )

    try:
        return await asyncio.to_thread(run)
    except WindowTooLong as exc:
        raise HTTPException(422, str(exc)) from None


_AnnotationId = Annotated[int, PathParam(ge=1, le=schema.INT64_MAX)]


@router.get("/trials/{trial_id}/annotations", dependencies=[allow("read")])
def list_annotations(trial_id: Id, c: Ctx) -> list[schema.ReviewAnnotation]:
    """The trial's notes by time: added in review, and taken live while it recorded (``source`` ``live``)."""
    return c.store.trial_notes(trial_id)


@router.post("/trials/{trial_id}/annotations", status_code=201)
async def add_annotation(
    trial_id: Id, c: Ctx, body: schema.ReviewAnnotationCreate, who: Annotator
) -> schema.ReviewAnnotation:
    """A note at a time (``t``) or over a span (``t`` to ``t_end``) of the trial, saved with it; 422 when it
    lies outside the recording."""
    from gaitscope.sessions.formats.mcap_io import read_series

    _, path = reviewable_trial(c, trial_id)
    ends = await asyncio.to_thread(read_series, path, None, None, 2)
    times = [t for t in ends["t"] if t is not None]
    if times:
        lo, hi = min(times), max(times)
        for name, value in (("t", body.t), ("t_end", body.t_end)):
            if value is not None and not lo - 0.01 <= value <= hi + 0.01:
                where = "start" if name == "t" else "end"
                raise HTTPException(
                    422, f"the note's {where} ({value:g} s) is outside the trial ({lo:.2f} to {hi:.2f} s)"
                )
    await audited(c, who, "review_note.add", f"trial {trial_id}", after=by(body, who))
    add = functools.partial(c.store.add_review_annotation, trial_id, by(body, who))
    return await c.writer.run(add, f"trial {trial_id}: review note")


@router.delete("/trials/{trial_id}/annotations/{annotation_id}", status_code=204)
def delete_annotation(trial_id: Id, annotation_id: _AnnotationId, c: Ctx, who: Annotator) -> Response:
    """Delete a note; only whoever wrote it may (403 for anyone else)."""
    audit(c, who, "review_note.delete", f"trial {trial_id} note {annotation_id}")
    try:
        c.store.delete_review_annotation(trial_id, annotation_id, who.name)
    except NotAllowed as exc:
        raise HTTPException(403, str(exc)) from None
    return Response(status_code=204)
