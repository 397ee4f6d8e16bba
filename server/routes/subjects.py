"""``/api/subjects``: the people who walk with a device."""

from __future__ import annotations

from fastapi import APIRouter

from server.routes.common import Ctx
from sessions import schema

router = APIRouter(prefix="/api")


@router.get("/subjects")
def list_subjects(c: Ctx) -> list[schema.Subject]:
    return c.store.list_subjects()


@router.post("/subjects", status_code=201)
def create_subject(body: schema.SubjectCreate, c: Ctx) -> schema.Subject:
    return c.store.create_subject(body)


@router.get("/subjects/{subject_id}")
def get_subject(subject_id: int, c: Ctx) -> schema.Subject:
    return c.store.get_subject(subject_id)
