"""``/api/models``: the models in the model store, with what each was trained on."""

from __future__ import annotations

from fastapi import APIRouter

from gaitscope.server.auth import allow
from gaitscope.server.routes.common import Ctx
from gaitscope.sessions import schema

router = APIRouter(prefix="/api")


@router.get("/models", dependencies=[allow("read")])
def list_models(c: Ctx) -> list[schema.ModelInfo]:
    return [schema.ModelInfo(name=n, provenance=c.models.get(n)[1]) for n in c.models.names()]
