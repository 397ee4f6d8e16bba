"""What every REST route module shares: the app context dependency, id parameters, domain errors as
HTTP statuses, and the two lookups that turn a missing model or an unreadable trial into an answer."""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

from fastapi import Depends, FastAPI, HTTPException, Query, Request, status
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse

from estimators.pipeline import TrainedModel
from sessions import schema
from sessions.errors import DataFormatError
from sessions.live.gp_learning import LearningRefused
from sessions.live.manager import SessionStateError
from sessions.live.runtime import ChangeNotSaved, DiskFull, SettingRejected
from sessions.store import Conflict, NotFound

if TYPE_CHECKING:
    from server.app import AppContext

__all__ = ["ERROR_STATUS", "Ctx", "OptionalId", "ctx", "install_error_handlers", "reviewable_trial", "trained_model"]


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
    LearningRefused: status.HTTP_422_UNPROCESSABLE_CONTENT,
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


def trained_model(c: AppContext, name: str) -> TrainedModel:
    """The model store's model ``name``; 422 if there is none."""
    try:
        return c.models.get(name)[0]
    except DataFormatError:
        raise HTTPException(422, f"model {name!r} does not exist") from None


def reviewable_trial(c: AppContext, trial_id: int) -> tuple[schema.Trial, Path]:
    """A trial whose recording can be read (not still recording, not damaged; 409 if so) and its file."""
    trial = c.store.get_trial(trial_id)
    if trial.status == "recording":
        raise HTTPException(409, f"trial {trial_id} is still recording; stop the recording to review it")
    if trial.status == "damaged":
        raise HTTPException(409, f"trial {trial_id}'s recording is damaged beyond repair (see its session's events)")
    return trial, c.settings.data_dir / trial.path
