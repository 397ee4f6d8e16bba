"""``/api/viewer``: the 3D leg view (viser, its own port): where it is, which session it follows, and
posing it at a time of a trial.

The view is one for everyone watching it, so choosing what it shows is a change of shared state: it takes
``run`` (a viewer watches what others chose) and a change of the session it follows is audited
(``leg_view.focus``). Posing it at a trial's time, many times a second while a reviewer drags the cursor, is
not (it stores nothing); the focus that posing drops is.
"""

from __future__ import annotations

import asyncio

from fastapi import APIRouter, HTTPException

from gaitscope.server.auth import Runner, Who, allow
from gaitscope.server.routes.common import Ctx, audit, reviewable_trial
from gaitscope.sessions import schema

router = APIRouter(prefix="/api")


@router.get("/viewer", dependencies=[allow("read")])
def viewer(c: Ctx) -> dict[str, str | None]:
    view = c.leg_view
    return {"url": None if view is None else view.url}


def _focus(c: Ctx, who: Who, session_id: int | None) -> None:
    """Make the view follow ``session_id`` (None: nothing; the review page poses it), audited if it changes."""
    if c.focus != session_id:
        audit(c, who, "leg_view.focus", "leg view", before=c.focus, after=session_id)
        c.focus = session_id


@router.post("/viewer/focus")
def viewer_focus(body: schema.ViewerFocus, c: Ctx, who: Runner) -> dict[str, int | None]:
    _focus(c, who, body.session_id)
    return {"session_id": c.focus}


@router.post("/viewer/show")
async def viewer_show(body: schema.ViewerShow, c: Ctx, who: Runner) -> dict[str, float]:
    """Pose the leg view at time ``t`` of a trial (the review page's cursor)."""
    from gaitscope.sessions.formats.mcap_io import read_series

    trial, path = reviewable_trial(c, body.trial_id)
    series = await asyncio.to_thread(read_series, path, body.t - 0.02, body.t + 0.02, 10)
    if not series.get("t"):
        raise HTTPException(404, f"trial {body.trial_id} has no sample near t = {body.t:g} s")
    i = min(range(len(series["t"])), key=lambda k: abs(series["t"][k] - body.t))
    state = schema.GaitState.model_validate({k: v[i] for k, v in series.items()})
    if c.leg_view is not None:
        subject = c.store.get_subject(c.store.get_session(trial.session_id).subject_id)
        _focus(c, who, None)
        c.leg_view.show(state, subject.leg_length_m, None)
    return {"t": state.t}
