"""``/api/subjects``: the people who walk with a device."""

from __future__ import annotations

from fastapi import APIRouter

from gaitscope.server.auth import LimitSetter, Runner, allow
from gaitscope.server.routes.common import Ctx, Id, audit
from gaitscope.sessions import schema

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
