"""``/api/estimators``: every estimator a session can run (``gaitscope.sessions.registry``), what it needs, what it
is for and what it costs per sample on this server (timed by the start-up warm-up,
:func:`gaitscope.sessions.live.warmup.warm_up`): what a new session's form offers."""

from __future__ import annotations

from fastapi import APIRouter

from gaitscope.estimators.descriptor import Descriptor
from gaitscope.server.auth import allow
from gaitscope.server.routes.common import Ctx
from gaitscope.sessions import registry, schema

router = APIRouter(prefix="/api")


@router.get("/estimators", dependencies=[allow("read")])
def list_estimators(c: Ctx) -> list[schema.RegisteredEstimator]:
    """Every registered estimator, in the order a stack runs them, with its cost per sample here (null when the
    warm-up did not time it). Which of them a source can feed stays the session's start to judge (409 naming
    the missing channels)."""
    return [_described(d, c.estimator_cost_us.get(d.name)) for d in registry.descriptors().values()]


def _described(d: Descriptor, cost_us: float | None) -> schema.RegisteredEstimator:
    return schema.RegisteredEstimator(
        name=d.name,
        label=d.label,
        purpose=d.purpose,
        paper=d.paper or None,
        inputs=list(d.inputs),
        inputs_any=list(d.inputs_any),
        optional_inputs=list(d.optional_inputs),
        phase=registry.DECLARED[d.name].phased,
        opt_in=d.opt_in,
        derives=d.derives,
        cost_us=cost_us,
    )
