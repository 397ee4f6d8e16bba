"""``/api/subjects``: the people who walk with a device, their assistance limits and speed-change intent model."""

from __future__ import annotations

import asyncio
import functools

from fastapi import APIRouter, HTTPException

from gaitscope.server.auth import LimitSetter, Promoter, Runner, allow
from gaitscope.server.routes.common import Ctx, Id, audit, audited, reviewable_trial
from gaitscope.sessions import schema
from gaitscope.sessions.personalization.intent_model import (
    IntentFitRefused,
    IntentModels,
    default_model,
    fit_from_trial,
)
from gaitscope.sessions.store import NotFound

router = APIRouter(prefix="/api")


@router.get("/subjects", dependencies=[allow("read")])
def list_subjects(c: Ctx) -> list[schema.Subject]:
    return c.store.list_subjects()


@router.post("/subjects", status_code=201)
def create_subject(body: schema.SubjectCreate, c: Ctx, who: Runner) -> schema.Subject:
    audit(c, who, "subject.create", body.code, after=body.model_dump())
    return c.store.create_subject(body)


@router.get("/subjects/{subject_id}", dependencies=[allow("read")])
def get_subject(subject_id: Id, c: Ctx) -> schema.Subject:
    return c.store.get_subject(subject_id)


@router.get("/subjects/{subject_id}/assistance-limits", dependencies=[allow("read")])
def assistance_limits(subject_id: Id, c: Ctx) -> schema.SubjectLimits | None:
    """The most assistance an experimenter may set for the subject; null: none set (an experimenter may not
    change assistance at all, nor start a device session)."""
    c.store.get_subject(subject_id)
    return c.accounts.limits(subject_id)


@router.put("/subjects/{subject_id}/assistance-limits")
def set_assistance_limits(
    subject_id: Id, body: schema.AssistanceLimits, c: Ctx, who: LimitSetter
) -> schema.SubjectLimits:
    """Set the experimenters' limits for the subject (clinicians and admins)."""
    old = c.accounts.limits(subject_id)
    before = None if old is None else old.model_dump(include=set(schema.AssistanceLimits.model_fields))
    audit(c, who, "limits.set", f"subject {subject_id}", before=before, after=body.model_dump())
    return c.accounts.set_limits(subject_id, body, by=who.name)


def _intent_models(c: Ctx) -> IntentModels:
    return IntentModels(c.store)


@router.get("/subjects/{subject_id}/intent-model", dependencies=[allow("read")])
def get_intent_model(subject_id: Id, c: Ctx) -> schema.IntentModel:
    """The speed-change intent model the subject's next session runs (the default when none was set)."""
    c.store.get_subject(subject_id)
    return _intent_models(c).get(subject_id) or default_model(subject_id, "uninjured", "system")


@router.put("/subjects/{subject_id}/intent-model")
async def set_intent_model(
    subject_id: Id, body: schema.IntentModelRequest, c: Ctx, who: Promoter
) -> schema.IntentModel:
    """Set the subject's intent model: fitted on a trial of theirs (in a worker thread; 422 with the reason when
    the trial cannot serve), or the variant's default. It runs from the subject's next session on (a running
    session keeps the model it started with, so nothing that drives a torque now changes)."""
    subject = c.store.get_subject(subject_id)
    models = _intent_models(c)
    old = models.get(subject_id)
    if body.trial_id is None:
        draft = default_model(subject_id, body.variant, who.name, body.note)
    else:
        trial, path = reviewable_trial(c, body.trial_id)
        if c.store.get_session(trial.session_id).subject_id != subject_id:
            raise HTTPException(422, f"trial {trial.id} is not of subject {subject_id}")
        try:
            kappa, alpha, steps, rmse = await asyncio.to_thread(
                fit_from_trial, path, subject.leg_length_m, body.variant
            )
        except IntentFitRefused as e:
            raise HTTPException(422, f"trial {trial.id} cannot fit an intent model: {e}") from None
        draft = schema.IntentModel(
            subject_id=subject_id, variant=body.variant, kappa=kappa, alpha=alpha,
            source=f"fitted on trial {trial.id} ({trial.name})", source_trial_id=trial.id, steps=steps,
            step_rmse_m=rmse, actor=who.name, updated_utc="", note=body.note,
        )  # fmt: skip
    before = None if old is None else old.model_dump(mode="json", include={"variant", "kappa", "alpha", "source"})
    after = draft.model_dump(mode="json", include={"variant", "kappa", "alpha", "source"})
    await audited(c, who, "intent_model.set", f"subject {subject_id}", before=before, after=after)
    return await c.writer.run(functools.partial(models.save, draft), f"subject {subject_id}: intent model")


@router.delete("/subjects/{subject_id}/intent-model")
async def reset_intent_model(subject_id: Id, c: Ctx, who: Promoter) -> schema.IntentModel:
    """Back to the default model (the cohort's kappa) from the subject's next session on; 404 when it is already."""
    c.store.get_subject(subject_id)
    models = _intent_models(c)
    old = models.get(subject_id)
    if old is None:
        raise NotFound(f"subject {subject_id} runs the default intent model already")
    before = old.model_dump(mode="json", include={"variant", "kappa", "alpha", "source"})
    await audited(c, who, "intent_model.reset", f"subject {subject_id}", before=before)
    await c.writer.run(functools.partial(models.delete, subject_id), f"subject {subject_id}: intent model")
    return default_model(subject_id, "uninjured", "system")
