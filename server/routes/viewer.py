"""``/api/viewer``: the 3D leg view (viser, its own port): where it is, which session it follows, and
posing it at a time of a trial."""

from __future__ import annotations

import asyncio

from fastapi import APIRouter, HTTPException

from server.auth import allow
from server.routes.common import Ctx, reviewable_trial
from sessions import schema

router = APIRouter(prefix="/api")


@router.get("/viewer", dependencies=[allow("read")])
def viewer(c: Ctx) -> dict[str, str | None]:
    view = c.leg_view
    return {"url": None if view is None else view.url}


@router.post("/viewer/focus", dependencies=[allow("read")])
def viewer_focus(body: schema.ViewerFocus, c: Ctx) -> dict[str, int | None]:
    c.focus = body.session_id
    return {"session_id": c.focus}


@router.post("/viewer/show", dependencies=[allow("read")])
async def viewer_show(body: schema.ViewerShow, c: Ctx) -> dict[str, float]:
    """Pose the leg view at time ``t`` of a trial (the review page's cursor)."""
    from sessions.formats.mcap_io import read_series

    trial, path = reviewable_trial(c, body.trial_id)
    series = await asyncio.to_thread(read_series, path, body.t - 0.02, body.t + 0.02, 10)
    if not series.get("t"):
        raise HTTPException(404, f"trial {body.trial_id} has no sample near t = {body.t:g} s")
    i = min(range(len(series["t"])), key=lambda k: abs(series["t"][k] - body.t))
    state = schema.GaitState.model_validate({k: v[i] for k, v in series.items()})
    if c.leg_view is not None:
        subject = c.store.get_subject(c.store.get_session(trial.session_id).subject_id)
        c.focus = None
        c.leg_view.show(state, subject.leg_length_m, None)
    return {"t": state.t}
