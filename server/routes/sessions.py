"""``/api/sessions``: create, start and stop sessions; change their settings while they run; their
events, annotations and recordings. Thin: validation by the schema, logic in ``gaitscope.sessions.live``."""

from __future__ import annotations

import functools
import logging

from fastapi import APIRouter, HTTPException

from gaitscope.server.auth import Annotator, Assistant, Runner, allow
from gaitscope.server.routes.common import (
    Ctx,
    Id,
    OptionalId,
    audited,
    by,
    check_assistance,
    not_running_here,
    trained_model,
)
from gaitscope.sessions import schema
from gaitscope.sessions.errors import FREE_SPACE_HINT, DiskFull, is_disk_full
from gaitscope.sessions.live.manager import SessionStateError
from gaitscope.sessions.store import Conflict

log = logging.getLogger("gaitscope")
router = APIRouter(prefix="/api")


@router.get("/sessions", dependencies=[allow("read")])
def list_sessions(c: Ctx, subject_id: OptionalId = None) -> list[schema.Session]:
    return [c.manager.shown(s) for s in c.store.list_sessions(subject_id)]


@router.post("/sessions", status_code=201)
async def create_session(body: schema.SessionCreate, c: Ctx, who: Runner) -> schema.Session:
    trained_model(c, body.settings.model)
    default_primary = schema.SessionSettings.model_fields["primary"].default
    if body.settings.primary != default_primary:  # choosing it is switching it: refused to an experimenter
        check_assistance(c, who, body.subject_id, {"primary": body.settings.primary})
    if isinstance(body.source, schema.DeviceSource | schema.LslSource):  # a person wears it: settings are assistance
        check_assistance(c, who, body.subject_id, body.settings.model_dump(exclude={"primary"}))
    await audited(c, who, "session.create", f"subject {body.subject_id}", after=body.model_dump(mode="json"))
    if isinstance(body.source, schema.ReplaySource):
        trial = c.manager.shown_trial(c.store.get_trial(body.source.trial_id))
        if trial.status in ("recording", "damaged"):
            why = "is still recording" if trial.status == "recording" else "has a damaged recording"
            raise SessionStateError(f"trial {trial.id} {why}; it cannot be replayed")
    session = await c.writer.run(functools.partial(c.store.create_session, body), "create session")
    return await c.manager.start_async(session.id, who.name) if body.start else session


@router.get("/sessions/{session_id}", dependencies=[allow("read")])
def get_session(session_id: Id, c: Ctx) -> schema.Session:
    return c.manager.shown(c.store.get_session(session_id))


@router.post("/sessions/{session_id}/start")
async def start_session(session_id: Id, c: Ctx, who: Runner) -> schema.Session:
    before = c.store.get_session(session_id)
    await audited(c, who, "session.start", f"session {session_id}", before=before.state, after="running")
    return await c.manager.start_async(session_id, who.name)


@router.post("/sessions/{session_id}/stop")
async def stop_session(session_id: Id, c: Ctx, who: Runner) -> schema.Session:
    """Stop a session. Stopping takes the assistance off the person, so it is never refused for want of an audit
    entry: when a full disk refuses the entry, the session stops all the same (the refusal is logged, and the
    session's own stop event, kept until the disk has room, names the stop) and the answer is 507 saying so."""
    before = c.store.get_session(session_id)
    try:
        await audited(c, who, "session.stop", f"session {session_id}", before=before.state, after="stopped")
    except Exception as e:
        if not is_disk_full(e) or before.state != "running":
            raise
        log.error("session %d: stopped by %s without its audit entry, which the full disk refused: %s",
                  session_id, who.name, e)  # fmt: skip
        await c.manager.stop(session_id)
        what = f"session {session_id} stopped, but its audit entry could not be written"
        raise DiskFull(f"{what}: {FREE_SPACE_HINT}") from e
    return await c.manager.stop(session_id)


@router.patch("/sessions/{session_id}/settings")
async def change_settings(session_id: Id, body: schema.SettingsChange, c: Ctx, who: Assistant) -> schema.Session:
    """Change a running session's settings. A change that can raise the torque on the person (a raise of the torque
    gain, the maximum torque or the intent boost, a switch of the primary) needs ``confirm``: without it the answer is
    409 with a ``TorqueRaiseRefused`` naming the peak torque before and after, to show and resend confirmed; at most
    one such change every ``TORQUE_RAISE_INTERVAL_S`` (``gaitscope.sessions.live.torque_rule``)."""
    runtime = c.manager.get(session_id)
    if runtime is None:
        c.store.get_session(session_id)
        raise SessionStateError(not_running_here(c, session_id, "; settings change only while it runs"))
    requested = body.model_dump(exclude={"actor", "reason", "confirm"}, exclude_none=True)
    check_assistance(c, who, runtime.session.subject_id, requested)
    current = runtime.session.settings.model_dump()
    before = {k: current[k] for k in requested}
    after = {**requested, "confirm": True} if body.confirm else requested  # a confirmed change says so
    await audited(c, who, "settings.change", f"session {session_id}", before=before, after=after, detail=body.reason)
    return await runtime.change_settings_async(by(body, who))  # stored (off the loop) before it is applied


@router.post("/sessions/{session_id}/settings/check", dependencies=[allow("read")])
async def check_settings(session_id: Id, body: schema.SettingsChange, c: Ctx) -> schema.TorqueCheck:
    """What a settings change would do to the torque of a running session, changing nothing: whether it needs
    ``confirm`` (``fields``), the peak torque before and after, how long until it may be made. The dashboard asks
    its user with it before it sends the change."""
    runtime = c.manager.get(session_id)
    if runtime is None:
        c.store.get_session(session_id)
        raise SessionStateError(not_running_here(c, session_id, "; settings change only while it runs"))
    return runtime.settings_changes.check(body)


@router.get("/sessions/{session_id}/events", dependencies=[allow("read")])
def session_events(session_id: Id, c: Ctx) -> list[schema.Event]:
    c.store.get_session(session_id)
    return c.store.list_events(session_id)


@router.post("/sessions/{session_id}/annotations", status_code=201)
async def annotate(session_id: Id, body: schema.AnnotationCreate, c: Ctx, who: Annotator) -> schema.Event:
    await audited(c, who, "session.annotate", f"session {session_id}", after={"text": body.text})
    runtime = c.manager.get(session_id)
    if runtime is not None:
        return runtime.annotate(body.text, who.name)
    c.store.get_session(session_id)
    add = functools.partial(c.store.add_event, session_id, t=0.0, kind="annotation", text=body.text, actor=who.name)
    return await c.writer.run(add, f"session {session_id}: annotation")


@router.post("/sessions/{session_id}/recording")
async def recording(session_id: Id, body: schema.RecordingControl, c: Ctx, who: Runner) -> schema.Trial:
    await audited(c, who, f"recording.{body.action}", f"session {session_id}", after=body.model_dump())
    runtime = c.manager.get(session_id)
    if runtime is None:
        raise HTTPException(409, not_running_here(c, session_id))
    if body.action == "start":
        if runtime.trial is not None:
            return runtime.trial  # already recording: that trial, under its own name
        return runtime.start_recording(_free_trial_name(c, session_id, body.name.strip()))
    trial = runtime.stop_recording()
    if trial is None:
        raise HTTPException(409, f"session {session_id} is not recording")
    return trial


def _free_trial_name(c: Ctx, session_id: int, name: str) -> str:
    """The name a new trial of the session gets: ``name`` if no trial of the session has it (409 if one does),
    or, for no name, the first free ``trial N`` (trial names are unique within a session)."""
    taken = {t.name.casefold() for t in c.store.list_trials(session_id)}
    if name:
        if name.casefold() in taken:
            raise Conflict(f"session {session_id} already has a trial named {name!r}: choose another name")
        return name
    number = len(taken) + 1
    while f"trial {number}" in taken:
        number += 1
    return f"trial {number}"
