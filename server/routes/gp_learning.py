"""``/api/sessions/{id}/gp-learning``: seed 003's GP-EKF learning the wearer in a running session: its state
for the dashboard (model versions, the learned joint angles with their band) and the clinician's controls
(freeze, unfreeze, roll back). Thin: the learning is ``gaitscope.sessions.live.gp_learning``'s; both routes run on the
event loop, between two samples, so they never see a sample half done."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, HTTPException, Query

from gaitscope.server.auth import Runner, allow
from gaitscope.server.routes.common import Ctx, Id, audited, by, not_running_here
from gaitscope.sessions import schema
from gaitscope.sessions.gp_models import GP_EKF
from gaitscope.sessions.live.gp_learning import GPLearning
from gaitscope.sessions.live.runtime import SessionRuntime

router = APIRouter(prefix="/api")


def _running(c: Ctx, session_id: int) -> tuple[SessionRuntime, GPLearning]:
    """The running session and its learning; 404 no such session, 409 not running or no GP-EKF."""
    runtime = c.manager.get(session_id)
    if runtime is None:
        c.store.get_session(session_id)
        raise HTTPException(409, not_running_here(c, session_id, "; its GP-EKF learns only while it runs"))
    if runtime.gp_learning is None:
        stack = ", ".join(runtime.estimator.stack.names)
        raise HTTPException(409, f"session {session_id} runs no GP-EKF: {GP_EKF} is not in its stack ({stack})")
    return runtime, runtime.gp_learning


@router.get("/sessions/{session_id}/gp-learning", dependencies=[allow("read")])
async def gp_learning(
    session_id: Id, c: Ctx, version: Annotated[int | None, Query(ge=0, le=schema.INT64_MAX)] = None
) -> schema.GPLearningState:
    """The GP-EKF's learning: the version in use, the one waiting for the next heel strike, a fit under way,
    the kept versions (training window, held-out RMSE, install times), frozen or not, and the learned mean of
    each joint angle with its +-2 sd band over stance phase for the version in use (and ``version``'s, a
    kept one: 422 otherwise). 409: not running, or no GP-EKF in its stack."""
    runtime, learning = _running(c, session_id)
    return learning.state(runtime.session.id, version)


@router.post("/sessions/{session_id}/gp-learning")
async def control_gp_learning(
    session_id: Id, body: schema.GPLearningControl, c: Ctx, who: Runner
) -> schema.GPLearningState:
    """Freeze or unfreeze the learning, or roll back to a kept version (installed at the next heel strike);
    logged as an event with the actor and recorded. 409: not running, no GP-EKF, or it failed; 422: a bad
    body, or a version that is not kept."""
    runtime, _ = _running(c, session_id)
    failed = runtime.estimator.stack.failed.get(GP_EKF)
    if failed is not None:
        raise HTTPException(409, f"session {session_id}'s GP-EKF has failed ({failed}); it learns no more")
    await audited(c, who, "gp_learning.control", f"session {session_id}", after=body.model_dump(exclude={"actor"}))
    assert runtime.learning is not None  # _running checked
    return runtime.learning.control(by(body, who))
