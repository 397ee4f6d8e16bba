"""REST routes (``/api``); thin: validation by the schema, logic in ``sessions``. See ``docs/api.md``."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

from fastapi import APIRouter, Body, Depends, FastAPI, HTTPException, Query, Request, status
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, JSONResponse
from pydantic import BaseModel, Field

from estimators.pipeline import TrainedModel
from sessions import schema
from sessions.errors import DataFormatError
from sessions.formats.models import gaitscope_version
from sessions.live.manager import SessionStateError
from sessions.live.runtime import ChangeNotSaved, DiskFull, SettingRejected
from sessions.store import Conflict, NotFound

if TYPE_CHECKING:
    from server.app import AppContext

router = APIRouter(prefix="/api")


def ctx(request: Request) -> AppContext:
    return request.app.state.ctx


Ctx = Annotated["AppContext", Depends(ctx)]
#: An id in a query filter: a positive signed 64-bit integer (what SQLite can hold).
OptionalId = Annotated[int | None, Query(ge=1, le=schema.INT64_MAX)]


#: Domain errors and the HTTP status each becomes (the message is the ``detail``).
ERROR_STATUS: dict[type[Exception], int] = {
    NotFound: status.HTTP_404_NOT_FOUND,
    Conflict: status.HTTP_409_CONFLICT,
    SessionStateError: status.HTTP_409_CONFLICT,
    SettingRejected: status.HTTP_409_CONFLICT,
    DataFormatError: status.HTTP_422_UNPROCESSABLE_CONTENT,
    ChangeNotSaved: status.HTTP_503_SERVICE_UNAVAILABLE,
    DiskFull: status.HTTP_507_INSUFFICIENT_STORAGE,
}


def install_error_handlers(app: FastAPI) -> None:
    """Routes raise domain errors; these handlers turn them into ``{"detail": message}`` responses."""

    def handler(code: int) -> Callable[[Request, Exception], Awaitable[JSONResponse]]:
        async def handle(_: Request, exc: Exception) -> JSONResponse:
            return JSONResponse({"detail": str(exc)}, status_code=code)

        return handle

    for exc_type, code in ERROR_STATUS.items():
        app.add_exception_handler(exc_type, handler(code))
    app.add_exception_handler(RequestValidationError, _validation_error)


async def _validation_error(_: Request, exc: Exception) -> JSONResponse:
    """422 with pydantic's errors, made JSON-safe: the offending input (which may hold NaN or
    Infinity, which JSON cannot carry) is left out, and context values become strings."""
    assert isinstance(exc, RequestValidationError)
    errors = [
        {
            "type": e.get("type"),
            "loc": list(e.get("loc", ())),
            "msg": e.get("msg"),
            **({"ctx": {k: str(v) for k, v in e["ctx"].items()}} if e.get("ctx") else {}),
        }
        for e in exc.errors()
    ]
    return JSONResponse({"detail": errors}, status_code=status.HTTP_422_UNPROCESSABLE_CONTENT)


@router.get("/health")
def health() -> dict[str, str]:
    return {"status": "ok", "version": gaitscope_version()}


_WIRE = (
    schema.SubjectCreate, schema.Subject, schema.SessionCreate, schema.Session, schema.SessionSettings,
    schema.SettingsChange, schema.Trial, schema.Event, schema.AnnotationCreate, schema.RecordingControl,
    schema.UploadCreate, schema.Upload, schema.RerunRequest, schema.SensorFrame, schema.GaitState,
    schema.TorqueCommand, schema.StreamBatch, schema.Health, schema.EventMessage, schema.SettingsMessage,
    schema.Hello, schema.FoxgloveEvent, schema.ModelProvenance, schema.DeviceNotice,
)  # fmt: skip


@router.get("/schema")
def wire_schema() -> dict[str, Any]:
    """JSON schema of every message that crosses a socket or a file."""
    return {cls.__name__: cls.model_json_schema() for cls in _WIRE}


# --- subjects ----------------------------------------------------------------------------------
@router.get("/subjects")
def list_subjects(c: Ctx) -> list[schema.Subject]:
    return c.store.list_subjects()


@router.post("/subjects", status_code=201)
def create_subject(body: schema.SubjectCreate, c: Ctx) -> schema.Subject:
    return c.store.create_subject(body)


@router.get("/subjects/{subject_id}")
def get_subject(subject_id: int, c: Ctx) -> schema.Subject:
    return c.store.get_subject(subject_id)


def _model(c: AppContext, name: str) -> TrainedModel:
    try:
        return c.models.get(name)[0]
    except DataFormatError:
        raise HTTPException(422, f"model {name!r} does not exist") from None


# --- sessions ----------------------------------------------------------------------------------
@router.get("/sessions")
def list_sessions(c: Ctx, subject_id: OptionalId = None) -> list[schema.Session]:
    return c.store.list_sessions(subject_id)


@router.post("/sessions", status_code=201)
async def create_session(body: schema.SessionCreate, c: Ctx) -> schema.Session:
    _model(c, body.settings.model)
    if isinstance(body.source, schema.ReplaySource):
        trial = c.store.get_trial(body.source.trial_id)
        if trial.status in ("recording", "damaged"):
            why = "is still recording" if trial.status == "recording" else "has a damaged recording"
            raise SessionStateError(f"trial {trial.id} {why}; it cannot be replayed")
    session = c.store.create_session(body)
    return c.manager.start(session.id) if body.start else session


@router.get("/sessions/{session_id}")
def get_session(session_id: int, c: Ctx) -> schema.Session:
    return c.store.get_session(session_id)


@router.post("/sessions/{session_id}/start")
async def start_session(session_id: int, c: Ctx) -> schema.Session:
    return c.manager.start(session_id)


@router.post("/sessions/{session_id}/stop")
async def stop_session(session_id: int, c: Ctx) -> schema.Session:
    return await c.manager.stop(session_id)


@router.patch("/sessions/{session_id}/settings")
async def change_settings(session_id: int, body: schema.SettingsChange, c: Ctx) -> schema.Session:
    runtime = c.manager.get(session_id)
    if runtime is None:
        c.store.get_session(session_id)
        raise SessionStateError(f"session {session_id} is not running; settings change only while it runs")
    return runtime.change_settings(body)


@router.get("/sessions/{session_id}/events")
def session_events(session_id: int, c: Ctx) -> list[schema.Event]:
    c.store.get_session(session_id)
    return c.store.list_events(session_id)


@router.post("/sessions/{session_id}/annotations", status_code=201)
async def annotate(session_id: int, body: schema.AnnotationCreate, c: Ctx) -> schema.Event:
    runtime = c.manager.get(session_id)
    if runtime is not None:
        return runtime.annotate(body.text, body.actor)
    c.store.get_session(session_id)
    return c.store.add_event(session_id, t=0.0, kind="annotation", text=body.text, actor=body.actor)


@router.post("/sessions/{session_id}/recording")
async def recording(session_id: int, body: schema.RecordingControl, c: Ctx) -> schema.Trial:
    runtime = c.manager.get(session_id)
    if runtime is None:
        raise HTTPException(409, f"session {session_id} is not running")
    if body.action == "start":
        return runtime.start_recording(body.name)
    trial = runtime.stop_recording()
    if trial is None:
        raise HTTPException(409, f"session {session_id} is not recording")
    return trial


# --- trials ------------------------------------------------------------------------------------
def _trial(c: AppContext, trial_id: int) -> tuple[schema.Trial, Path]:
    trial = c.store.get_trial(trial_id)
    if trial.status == "recording":
        raise HTTPException(409, f"trial {trial_id} is still recording; stop the recording to review it")
    if trial.status == "damaged":
        raise HTTPException(409, f"trial {trial_id}'s recording is damaged beyond repair (see its session's events)")
    return trial, c.settings.data_dir / trial.path


@router.get("/trials")
def list_trials(c: Ctx, session_id: OptionalId = None) -> list[schema.Trial]:
    return c.store.list_trials(session_id)


@router.get("/trials/{trial_id}")
def get_trial(trial_id: int, c: Ctx) -> schema.Trial:
    return c.store.get_trial(trial_id)


@router.get("/trials/{trial_id}/events")
def trial_events(trial_id: int, c: Ctx) -> list[schema.Event]:
    c.store.get_trial(trial_id)
    return c.store.trial_events(trial_id)


#: Session time bounds of a series (s): finite (FastAPI reads "nan", "inf" and "1e400" as floats) and
#: within about 30 years, so that ``t * 1e9`` is an integer nanosecond time.
_SeriesTime = Annotated[
    float | None, Query(allow_inf_nan=False, ge=-1e9, le=1e9, description="session time (s); none: unbounded")
]


@router.get("/trials/{trial_id}/series")
async def trial_series(
    trial_id: int,
    c: Ctx,
    t0: _SeriesTime = None,
    t1: _SeriesTime = None,
    max_points: Annotated[int, Query(ge=10, le=20000)] = 2000,
) -> dict[str, list[Any]]:
    from sessions.formats.mcap_io import read_series

    _, path = _trial(c, trial_id)
    return await asyncio.to_thread(read_series, path, t0, t1, max_points)


@router.get("/trials/{trial_id}/download")
def download(trial_id: int, c: Ctx) -> FileResponse:
    trial, path = _trial(c, trial_id)
    return FileResponse(path, media_type="application/octet-stream", filename=f"gaitscope_trial{trial.id}.mcap")


@router.get("/trials/{trial_id}/settings")
async def trial_settings(trial_id: int, c: Ctx) -> schema.SessionSettings:
    """The settings in force at the trial's first frame, as recorded (its changes are on ``/events``)."""
    from sessions.review.rerun import recorded_settings

    _, path = _trial(c, trial_id)
    return await asyncio.to_thread(recorded_settings, path)


@router.post("/trials/{trial_id}/rerun")
async def rerun(
    trial_id: int,
    c: Ctx,
    body: Annotated[schema.RerunRequest | None, Body()] = None,
    t0: _SeriesTime = None,
    t1: _SeriesTime = None,
    max_points: Annotated[int, Query(ge=10, le=20000)] = 2000,
) -> dict[str, list[Any]]:
    """The trial's raw frames through the estimators again (series like ``/series``): as recorded by
    default, or with the body's settings over the whole trial (what if); see ``RerunRequest``."""
    from sessions.review.rerun import rerun_series

    trial, path = _trial(c, trial_id)
    subject = c.store.get_subject(c.store.get_session(trial.session_id).subject_id)
    settings = None if body is None else body.settings

    def model(name: str) -> TrainedModel:
        return _model(c, name)

    return await asyncio.to_thread(
        rerun_series, path, model, subject.leg_length_m, subject.mass_kg, settings, t0, t1, max_points
    )


# --- models and the leg view -------------------------------------------------------------------
class ModelInfo(BaseModel):
    name: str
    provenance: schema.ModelProvenance


@router.get("/models")
def list_models(c: Ctx) -> list[ModelInfo]:
    return [ModelInfo(name=n, provenance=c.models.get(n)[1]) for n in c.models.names()]


class ViewerFocus(BaseModel):
    session_id: int = Field(ge=1)


class ViewerShow(BaseModel):
    trial_id: int = Field(ge=1)
    t: float


@router.get("/viewer")
def viewer(c: Ctx) -> dict[str, str | None]:
    view = c.leg_view
    return {"url": None if view is None else view.url}


@router.post("/viewer/focus")
def viewer_focus(body: ViewerFocus, c: Ctx) -> dict[str, int | None]:
    c.focus = body.session_id
    return {"session_id": c.focus}


@router.post("/viewer/show")
async def viewer_show(body: ViewerShow, c: Ctx) -> dict[str, float]:
    """Pose the leg view at time ``t`` of a trial (the review page's cursor)."""
    from sessions.formats.mcap_io import read_series

    trial, path = _trial(c, body.trial_id)
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
