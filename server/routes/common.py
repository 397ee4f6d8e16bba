"""What every REST route module shares: the app context dependency, id parameters, domain errors as
HTTP statuses, and the two lookups that turn a missing model or an unreadable trial into an answer."""

from __future__ import annotations

import functools
from collections.abc import Awaitable, Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Final, TypeVar

from fastapi import Depends, FastAPI, HTTPException, Query, Request, status
from fastapi import Path as PathParam
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel
from sqlalchemy.exc import DBAPIError

from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.sessions import schema
from gaitscope.sessions.errors import FREE_SPACE_HINT, DataFormatError, DiskFull, is_disk_full
from gaitscope.sessions.live.gp_learning import LearningRefused
from gaitscope.sessions.live.manager import SessionStateError
from gaitscope.sessions.live.runtime import ChangeNotSaved, SettingRejected
from gaitscope.sessions.live.settings_change import TorqueRaiseRejected
from gaitscope.sessions.store import Conflict, NotFound

if TYPE_CHECKING:
    from gaitscope.server.app import AppContext
    from gaitscope.server.auth import Who

__all__ = [
    "ERROR_STATUS",
    "LIMITED_SETTINGS",
    "Ctx",
    "Id",
    "OptionalId",
    "by",
    "check_assistance",
    "ctx",
    "install_error_handlers",
    "reviewable_trial",
    "trained_model",
]


def ctx(request: Request) -> AppContext:
    return request.app.state.ctx


Ctx = Annotated["AppContext", Depends(ctx)]
#: An id in a query filter: a positive signed 64-bit integer (what SQLite can hold).
OptionalId = Annotated[int | None, Query(ge=1, le=schema.INT64_MAX)]
#: An id in a path, bounded so: 2**63 is a 422 naming the parameter, not the database's overflow (a 500).
Id = Annotated[int, PathParam(ge=1, le=schema.INT64_MAX)]


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
    """Routes raise domain errors; these handlers turn them into ``{"detail": message}`` responses (a settings
    change refused by the torque rule: ``{"detail": TorqueRaiseRefused}``, its peaks before and after).

    A full disk is 507 wherever it is met: :class:`~gaitscope.sessions.errors.DiskFull`, a domain error raised
    from one (a change not saved), and the database's or the file system's own error (SQLite's
    "database or disk is full", PostgreSQL's 53100, ``ENOSPC``), which would otherwise be a 500."""

    def handler(code: int) -> Callable[[Request, Exception], Awaitable[JSONResponse]]:
        async def handle(_: Request, exc: Exception) -> JSONResponse:
            if code != status.HTTP_507_INSUFFICIENT_STORAGE and is_disk_full(exc):
                return _disk_full(f"{exc}: the server's disk is full; {FREE_SPACE_HINT}")
            if isinstance(exc, TorqueRaiseRejected):  # the peaks before and after, for the client to show
                return JSONResponse({"detail": exc.detail.model_dump(mode="json")}, status_code=code)
            return JSONResponse({"detail": str(exc)}, status_code=code)

        return handle

    for exc_type, code in ERROR_STATUS.items():
        app.add_exception_handler(exc_type, handler(code))
    app.add_exception_handler(RequestValidationError, _validation_error)
    for storage_error in (DBAPIError, OSError):
        app.add_exception_handler(storage_error, _storage_error)


def _disk_full(detail: str) -> JSONResponse:
    return JSONResponse({"detail": detail}, status_code=status.HTTP_507_INSUFFICIENT_STORAGE)


async def _storage_error(request: Request, exc: Exception) -> JSONResponse:
    """507 for a database or file error that says the disk is full; any other is re-raised (a 500: a server fault)."""
    if request.scope["type"] != "http" or not is_disk_full(exc):
        raise exc
    done = "nothing was read" if request.method in ("GET", "HEAD") else "nothing was changed"
    return _disk_full(f"{request.method} {request.url.path}: {done}: the server's disk is full; {FREE_SPACE_HINT}")


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
    trial = c.manager.shown_trial(c.store.get_trial(trial_id))
    if trial.status == "recording":
        raise HTTPException(409, f"trial {trial_id} is still recording; stop the recording to review it")
    if trial.status == "damaged":
        raise HTTPException(409, f"trial {trial_id}'s recording is damaged beyond repair (see its session's events)")
    return trial, c.settings.data_dir / trial.path


#: Settings that are assistance: an experimenter sets them only within the subject's limits (the noise scales
#: are estimator tuning, theirs to change).
LIMITED_SETTINGS: Final = ("torque_gain", "max_torque_Nm", "intent_gain_boost")


def check_assistance(c: AppContext, who: Who, subject_id: int, values: Mapping[str, Any]) -> None:
    """Refuse (403) assistance an experimenter may not set for this subject: over the limits a clinician set, any
    at all while none are set, or a switch of the estimator driving the torque. Those who may ``assist`` pass."""
    if who.may("assist"):
        return
    if values.get("primary") is not None:
        raise HTTPException(
            403, f"{who.role} {who.name!r} may not switch the estimator driving the torque: ask a clinician"
        )
    requested = {k: float(v) for k in LIMITED_SETTINGS if (v := values.get(k)) is not None}
    if not requested:
        return
    limits = c.accounts.limits(subject_id)
    if limits is None:
        raise HTTPException(
            403, f"subject {subject_id} has no assistance limits: a clinician sets them before an experimenter may "
            "change assistance",
        )  # fmt: skip
    over = [
        f"{k} {v:g} over the limit of {getattr(limits, k):g}" for k, v in requested.items() if v > getattr(limits, k)
    ]
    if over:
        raise HTTPException(403, f"over the clinician's limits for subject {subject_id}: {', '.join(over)}")


_B = TypeVar("_B", bound=BaseModel)


def by(body: _B, who: Who) -> _B:
    """The request body with its ``actor`` set to the caller: who did it is the login's, never the body's."""
    return body.model_copy(update={"actor": who.name})


def audit(
    c: AppContext, who: Who, action: str, target: str, *, before: Any = None, after: Any = None, detail: str = ""
) -> None:
    """Write a change to the audit trail before it takes effect (``gaitscope.sessions.audit``); a failure to write it
    refuses the change (the exception propagates: 500), so that nothing happens unaudited."""
    c.audit.record(
        user=who.name, role=who.role, action=action, target=target, before=before, after=after, detail=detail
    )


async def audited(
    c: AppContext, who: Who, action: str, target: str, *, before: Any = None, after: Any = None, detail: str = ""
) -> None:
    """:func:`audit` for an ``async`` route: the entry is written by the database writer (``c.writer``,
    :mod:`gaitscope.sessions.store_writer`) while the route waits, so the event loop and the sessions on it do not;
    written before the change takes effect, and a failure to write it refuses the change, as there."""
    record = functools.partial(
        c.audit.record, user=who.name, role=who.role, action=action, target=target, before=before, after=after,
        detail=detail,
    )  # fmt: skip
    await c.writer.run(record, f"audit entry {action} {target}")


def not_running_here(c: AppContext, session_id: int, what: str = "") -> str:
    """Why session ``session_id`` has no runtime in this process, in words: it does not exist (NotFound), it is
    not running, or it runs in another process (its node) sharing the database. ``what``: "; <what it needs>"."""
    session = c.manager.shown(c.store.get_session(session_id))
    if session.state == "running" and session.node not in (None, c.manager.node):
        return f"session {session_id} runs on {session.node}, not on this server ({c.manager.node}): use that one"
    if (unsaved := c.manager.unsaved.get(session_id)) is not None:  # it ended here: say why
        return f"session {session_id} is {session.state} ({unsaved.reason}){what}"
    if session.state in ("stopped", "failed"):  # ended elsewhere, or by a node that took another's over: say why
        ended = [e.text for e in c.store.list_events(session_id) if e.kind == "system"]
        if ended:
            return f"session {session_id} is not running ({ended[-1]}){what}"
    return f"session {session_id} is not running{what}"
