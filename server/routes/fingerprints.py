"""``/api/subjects/{id}/fingerprints``: a subject's personalized gait models (seed 004's fingerprints):
calibrate from a trial, list, promote, roll back, export and import. Every change is a row of the subject's
history (who, when) and, for each running session of the subject, an event in its log."""

from __future__ import annotations

import asyncio
import functools
import math

from fastapi import APIRouter, HTTPException
from fastapi.responses import JSONResponse

from gaitscope.estimators.fingerprint import FingerprintMap
from gaitscope.server.auth import Promoter, Reader, Runner, Uploader, allow
from gaitscope.server.routes.common import Ctx, Id, audit, audited, reviewable_trial
from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.personalization.calibration import CalibrationRefused, calibrate, read_walk
from gaitscope.sessions.registry import DESCRIPTORS

router = APIRouter(prefix="/api")
#: The fingerprint filter that runs the subject's active personalization (its descriptor's role ``personal``).
PERSONAL_FILTER = next(d.name for d in DESCRIPTORS if d.fingerprint == "personal")


def _map(c: Ctx, model: str) -> tuple[FingerprintMap, schema.ModelProvenance]:
    try:
        trained, prov = c.models.get(model)
    except DataFormatError:  # as common.trained_model: no such model file, or not a model
        raise HTTPException(422, f"model {model!r} does not exist") from None
    if trained.fingerprints is None:
        raise HTTPException(422, f"model {model!r} has no fingerprint map (it was trained without thigh angles)")
    return trained.fingerprints, prov


def _listing(c: Ctx, subject_id: int, model: str) -> schema.Fingerprints:
    versions = c.store.list_personalizations(subject_id, model)
    try:
        fmap, prov = _map(c, model)
    except HTTPException:
        return schema.Fingerprints(
            subject_id=subject_id, model=model, components=0, explained=[], active=None, versions=versions, cohort=[]
        )
    codes = list(prov.subjects) if len(prov.subjects) == len(fmap.training_g) else []
    cohort = [
        schema.CohortPoint(code=codes[i] if codes else f"training subject {i + 1}", fingerprint=g.tolist())
        for i, g in enumerate(fmap.training_g)
    ]
    return schema.Fingerprints(
        subject_id=subject_id,
        model=model,
        components=fmap.n_components,
        explained=fmap.explained.tolist(),
        active=next((v for v in versions if v.state == "active"), None),
        versions=versions,
        cohort=cohort,
    )


@router.get("/subjects/{subject_id}/fingerprints", dependencies=[allow("read")])
def list_fingerprints(subject_id: Id, c: Ctx, model: str = "default") -> schema.Fingerprints:
    """The subject's personalizations of ``model``, newest first, the active one, and the training
    subjects' fingerprints (where this subject sits among them)."""
    c.store.get_subject(subject_id)
    return _listing(c, subject_id, model)


@router.post("/subjects/{subject_id}/fingerprints", status_code=201)
async def calibrate_fingerprint(
    subject_id: Id, body: schema.CalibrationRequest, c: Ctx, who: Runner
) -> schema.Personalization:
    """Fit a fingerprint from one of the subject's trials, in a worker thread (live streams go on); stored
    as a ``candidate``: nothing runs it until it is promoted. 422 with the reason when the walk cannot serve."""
    c.store.get_subject(subject_id)
    trial, path = reviewable_trial(c, body.trial_id)
    if c.store.get_session(trial.session_id).subject_id != subject_id:
        raise HTTPException(422, f"trial {trial.id} is not of subject {subject_id}")
    fmap, _ = _map(c, body.model)
    await audited(c, who, "fingerprint.calibrate", f"subject {subject_id}", after=body.model_dump(mode="json"))

    def fit() -> schema.Personalization:
        cal = calibrate(fmap, read_walk(path))
        return schema.Personalization(
            id=0,
            subject_id=subject_id,
            version=0,
            model=body.model,
            fingerprint=cal.fingerprint.tolist(),
            fit_rmse_avg_deg=cal.fit_rmse_avg_deg,
            fit_rmse_personal_deg=cal.fit_rmse_personal_deg,
            source_trial_id=trial.id,
            strides_used=cal.strides_used,
            strides_excluded=cal.strides_excluded,
            seconds_used=cal.seconds_used,
            excluded=cal.excluded,
            stride_length_source=cal.stride_length_source,
            state="candidate",
            created_utc="",
            created_by=who.name,
            note=body.note,
        )

    try:
        draft = await asyncio.to_thread(fit)
    except CalibrationRefused as e:
        raise HTTPException(422, f"trial {trial.id} cannot calibrate a fingerprint: {e}") from None
    if not all(math.isfinite(x) for x in draft.fingerprint):
        raise HTTPException(422, f"trial {trial.id} gave no finite fingerprint")
    add = functools.partial(c.store.add_personalization, draft)
    return await c.writer.run(add, f"subject {subject_id}: fingerprint")


def _confirmed(c: Ctx, subject_id: int, body: schema.PersonalizationChange, what: str) -> None:
    """409 unless ``body`` is confirmed when a running session of the subject has its torque follow the
    personalized filter (``fp_ls``): the change reaches that torque live (issue #23: every change of what
    drives the torque asks first, for API clients as for the dashboard)."""
    if body.confirm:
        return
    driven = sorted(
        r.session.id
        for r in c.manager.running()
        if r.session.subject_id == subject_id and r.estimator.stack.primary == PERSONAL_FILTER
    )
    if driven:
        sessions = ", ".join(map(str, driven))
        raise HTTPException(
            409,
            f"the torque of running session {sessions} follows the personalized filter ({PERSONAL_FILTER}): "
            f"{what} changes what drives it at its next heel strike; confirm it (confirm: true) to make it",
        )


def _announce(c: Ctx, subject_id: int, text: str, actor: str) -> None:
    """An event in the log of every running session of the subject (a promotion reaches them live)."""
    for runtime in c.manager.running():
        if runtime.session.subject_id == subject_id:
            runtime.personalization.changed(text, actor)


@router.post("/subjects/{subject_id}/fingerprints/{personalization_id}/promote")
def promote_fingerprint(
    subject_id: Id, personalization_id: Id, body: schema.PersonalizationChange, c: Ctx, who: Promoter
) -> schema.Personalization:
    """Make it the subject's active personalization; running sessions take it at their next heel strike."""
    p = c.store.get_personalization(personalization_id)
    if p.subject_id != subject_id:
        raise HTTPException(404, f"personalization {personalization_id} is not of subject {subject_id}")
    _map(c, p.model)  # the model must still have its map
    _confirmed(c, subject_id, body, f"promoting v{p.version}")
    active = c.store.active_personalization(subject_id, p.model)
    target = f"subject {subject_id} model {p.model}"
    before, after = None if active is None else f"v{active.version}", f"v{p.version}"
    audit(c, who, "fingerprint.promote", target, before=before, after=after, detail=body.reason)
    done = c.store.promote_personalization(personalization_id, who.name)
    why = f" ({body.reason})" if body.reason else ""
    _announce(c, subject_id, f"personalized model v{done.version} promoted by {who.name}{why}", who.name)
    return done


@router.post("/subjects/{subject_id}/fingerprints/rollback")
def rollback_fingerprint(
    subject_id: Id, body: schema.PersonalizationChange, c: Ctx, who: Promoter, model: str = "default"
) -> schema.Fingerprints:
    """Retire the active personalization; the one it replaced is active again (none: the average model)."""
    active = c.store.active_personalization(subject_id, model)
    if active is not None:
        _confirmed(c, subject_id, body, f"rolling back v{active.version}")
    before = None if active is None else f"v{active.version}"
    audit(c, who, "fingerprint.rollback", f"subject {subject_id} model {model}", before=before, detail=body.reason)
    old, now = c.store.rollback_personalization(subject_id, model, who.name)
    to = "the average model" if now is None else f"v{now.version}"
    why = f" ({body.reason})" if body.reason else ""
    _announce(c, subject_id, f"personalized model v{old.version} rolled back to {to} by {who.name}{why}", who.name)
    return _listing(c, subject_id, model)


@router.get("/subjects/{subject_id}/fingerprints/{personalization_id}/export")
def export_fingerprint(subject_id: Id, personalization_id: Id, c: Ctx, who: Reader) -> JSONResponse:
    """The personalization as a file another gaitscope can import (with the same model)."""
    p = c.store.get_personalization(personalization_id)
    if p.subject_id != subject_id:
        raise HTTPException(404, f"personalization {personalization_id} is not of subject {subject_id}")
    _, prov = _map(c, p.model)
    subject = c.store.get_subject(subject_id)
    out = schema.PersonalizationExport(
        subject_code=subject.code,
        model=p.model,
        model_sha256=prov.source_sha256,
        fingerprint=p.fingerprint,
        fit_rmse_avg_deg=p.fit_rmse_avg_deg,
        fit_rmse_personal_deg=p.fit_rmse_personal_deg,
        strides_used=p.strides_used,
        seconds_used=p.seconds_used,
        created_utc=p.created_utc,
        note=p.note,
    )
    name = f"{subject.code}-fingerprint-v{p.version}.json"
    audit(c, who, "fingerprint.export", f"subject {subject_id} personalization {personalization_id}")
    return JSONResponse(out.model_dump(), headers={"Content-Disposition": f'attachment; filename="{name}"'})


@router.post("/subjects/{subject_id}/fingerprints/import", status_code=201)
def import_fingerprint(
    subject_id: Id, body: schema.PersonalizationExport, c: Ctx, who: Uploader
) -> schema.Personalization:
    """A personalization exported elsewhere, as a new ``candidate``; refused (422) when its model's map is
    not this machine's (another training-data hash, or another number of components)."""
    c.store.get_subject(subject_id)
    fmap, prov = _map(c, body.model)
    if body.model_sha256 != prov.source_sha256:
        raise HTTPException(
            422, f"the fingerprint belongs to another version of model {body.model!r} (its training data differ)"
        )
    if len(body.fingerprint) != fmap.n_components:
        raise HTTPException(
            422, f"the fingerprint has {len(body.fingerprint)} components; model {body.model!r} has {fmap.n_components}"
        )
    audit(c, who, "fingerprint.import", f"subject {subject_id}", after=body.model_dump(mode="json"))
    return c.store.add_personalization(
        schema.Personalization(
            id=0,
            subject_id=subject_id,
            version=0,
            model=body.model,
            fingerprint=body.fingerprint,
            fit_rmse_avg_deg=body.fit_rmse_avg_deg,
            fit_rmse_personal_deg=body.fit_rmse_personal_deg,
            source_trial_id=None,
            strides_used=body.strides_used,
            strides_excluded=0,
            seconds_used=body.seconds_used,
            excluded={},
            stride_length_source="imported",
            state="candidate",
            created_utc="",
            created_by="import",
            note=body.note or f"imported from {body.subject_code} ({body.created_utc})",
        )
    )
