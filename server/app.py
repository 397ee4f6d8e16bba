"""The FastAPI application: REST API, websockets, the browser UI and the leg view, wired together.

``create_app(settings)`` builds everything; the lifespan opens the database, re-indexes recordings a
crash left unfinished, starts the viser leg view in its own thread and port, and (on an empty database)
creates a demo subject with a simulated session, so ``gaitscope serve`` shows a live session at once.
"""

from __future__ import annotations

import asyncio
import functools
import gc
import logging
import time
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from dataclasses import dataclass, field
from pathlib import Path

from fastapi import FastAPI
from fastapi.staticfiles import StaticFiles

from gaitscope.server.audit_middleware import AuditMiddleware
from gaitscope.server.leg_view import LegView
from gaitscope.server.origin import AllowedHostsMiddleware, SameOriginMiddleware
from gaitscope.server.routes import ROUTERS, Uploads, install_error_handlers
from gaitscope.server.settings import Settings
from gaitscope.server.ws_close import ServerSendMiddleware
from gaitscope.sessions import schema
from gaitscope.sessions.accounts import Accounts
from gaitscope.sessions.audit import AuditLog
from gaitscope.sessions.audit.key import settings_key
from gaitscope.sessions.cluster.membership import keep_membership
from gaitscope.sessions.cluster.nodes import Nodes
from gaitscope.sessions.formats.models import gaitscope_version
from gaitscope.sessions.live.disk import DiskGuard
from gaitscope.sessions.live.gp_learning import GPTrainer
from gaitscope.sessions.live.manager import ModelStore, SessionManager
from gaitscope.sessions.live.warmup import warm_up
from gaitscope.sessions.mappings.saved import SavedMappings
from gaitscope.sessions.store import Store
from gaitscope.sessions.store_writer import StoreWriter

log = logging.getLogger("gaitscope")
WEB_DIR = Path(__file__).resolve().parent.parent / "web"
#: Leg-view updates per second, at most (a browser iframe needs no more).
LEG_VIEW_HZ = 30.0


@dataclass
class AppContext:
    """What the routes need; one per app, on ``app.state.ctx``."""

    settings: Settings
    store: Store
    models: ModelStore
    manager: SessionManager
    uploads: Uploads
    accounts: Accounts
    audit: AuditLog
    #: the thread that makes the event loop's database writes (sessions' events and trials, async routes' audit)
    writer: StoreWriter
    #: the channel mappings saved per rig (uploads of other tools' MCAP recordings and of C3D files)
    mappings: SavedMappings
    leg_view: LegView | None = None
    #: this node's membership of a cluster (Settings.cluster), else None
    nodes: Nodes | None = None
    #: each registered estimator's median time per sample on this machine (microseconds) by name, as the
    #: start-up warm-up timed it (``GET /api/estimators``); empty until it ran
    estimator_cost_us: dict[str, float] = field(default_factory=dict)

    focus: int | None = None
    _last_view: float = 0.0

    def on_state(self, session_id: int, state: schema.GaitState, leg_length: float) -> None:
        """Feed the leg view with the focused session, rate-limited."""
        if self.leg_view is None or session_id != self.focus:
            return
        now = time.monotonic()
        if now - self._last_view >= 1.0 / LEG_VIEW_HZ:
            self._last_view = now
            self.leg_view.show(state, leg_length, session_id)


def _cookie_logged_in(accounts: Accounts, cookie_header: str) -> int | None:
    """The open login a ``Cookie`` header holds, by id, if any (the leg view's own server asks)."""
    from http.cookies import CookieError, SimpleCookie

    from gaitscope.server.auth import COOKIE

    try:
        morsel = SimpleCookie(cookie_header).get(COOKIE)
    except CookieError:
        return None
    login = None if morsel is None else accounts.identify(morsel.value)
    return None if login is None else login.login_id


def _audit_key(settings: Settings) -> bytes:
    """The audit trail's key: ``GAITSCOPE_AUDIT_KEY``, else the data folder's ``audit.key`` (made at first start)."""
    key = settings_key(settings, create=True)
    assert key is not None  # created if missing
    return key


def _api_docs(app: FastAPI) -> None:
    """``/openapi.json``, ``/docs`` and ``/redoc``, as FastAPI serves them, but only to who may read (with accounts
    on: a login): the API's description names every route and field, which is no one's business before logging in.
    Left out of the OpenAPI document itself, as FastAPI's own are."""
    from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
    from fastapi.responses import HTMLResponse, JSONResponse

    from gaitscope.server.auth import allow

    read = [allow("read")]

    @app.get("/openapi.json", include_in_schema=False, dependencies=read)
    def openapi() -> JSONResponse:
        return JSONResponse(app.openapi())

    @app.get("/docs", include_in_schema=False, dependencies=read)
    def docs() -> HTMLResponse:
        return get_swagger_ui_html(openapi_url="/openapi.json", title=f"{app.title} - API")

    @app.get("/redoc", include_in_schema=False, dependencies=read)
    def redoc() -> HTMLResponse:
        return get_redoc_html(openapi_url="/openapi.json", title=f"{app.title} - API")


def _demo(ctx: AppContext) -> None:
    """An empty database gets a demo subject walking seed 000's treadmill protocol."""
    if ctx.store.list_subjects():
        return
    from gaitscope.sessions.live.sources import SimulatedDevice

    leg, mass = SimulatedDevice(schema.SimulatedSource()).subject_body()
    subject = ctx.store.create_subject(
        schema.SubjectCreate(code="DEMO01", leg_length_m=leg, mass_kg=mass, notes="virtual subject VC01")
    )
    session = ctx.store.create_session(schema.SessionCreate(subject_id=subject.id))
    ctx.manager.start(session.id)
    ctx.focus = session.id


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or Settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        settings.data_dir.mkdir(parents=True, exist_ok=True)
        store = Store(settings.database_url)
        models = ModelStore(settings.data_dir / "models")
        disk = DiskGuard(settings.data_dir, settings.disk_warn_mb, settings.disk_stop_mb)
        writer = StoreWriter()
        manager = SessionManager(
            store,
            settings.data_dir,
            models,
            on_state=lambda *a: ctx.on_state(*a),
            disk_check=disk.check,
            disk_room=disk.room,
            gp_trainer=GPTrainer(duty=settings.gp_fit_duty, nice=settings.gp_fit_nice),
            node=settings.node,
            writer=writer,
        )
        accounts = Accounts(
            store, lockout_after=settings.lockout_after, lockout_minutes=settings.lockout_minutes,
            login_hours=settings.login_hours,
        )  # fmt: skip
        audit = AuditLog(store, _audit_key(settings))
        audit.ensure_keyed()  # a trail from before the key: its keyed part starts here; another key: refused
        ctx = AppContext(
            settings=settings, store=store, models=models, manager=manager, uploads=Uploads(settings),
            accounts=accounts, audit=audit, writer=writer, mappings=SavedMappings(store),
        )  # fmt: skip
        ctx.uploads.clear_leftovers()  # uploads live in memory: a restart ends them
        for trial in ctx.manager.recover_after_crash():
            log.warning("recording of trial %d was unfinished and has been recovered", trial.id)
        if settings.leg_view:
            model = models.get("default")[0]
            logged_in = functools.partial(_cookie_logged_in, accounts) if settings.auth else None
            ctx.leg_view = LegView(
                settings.host,
                settings.viser_port,
                model,
                allowed_hosts=settings.allowed_hosts,
                logged_in=logged_in,
                watch=accounts.watch,
            )
        app.state.ctx = ctx
        # compile the kernels before answering, and time each estimator's step now that it is compiled
        ctx.estimator_cost_us = await asyncio.to_thread(warm_up, models.get("default")[0])
        # What start-up made (numpy, scipy, numba, pandas, the model: millions of objects) lives as long as
        # the server: kept out of the cyclic collector, whose full passes over it stalled the sessions'
        # event loop for tens of milliseconds (the load benchmark's p99).
        gc.collect()
        gc.freeze()
        if settings.demo:
            _demo(ctx)
        membership = None
        if settings.cluster:
            ctx.nodes = Nodes(store, settings.node, settings.node_address, settings.node_timeout_s)
            await writer.run(ctx.nodes.register, "node register")
            membership = asyncio.create_task(keep_membership(ctx.nodes, manager, writer), name="cluster membership")
        try:
            yield
        finally:
            if membership is not None:
                membership.cancel()
            await ctx.manager.stop_all()
            await asyncio.to_thread(writer.close)  # every write the sessions queued is made before the store closes
            ctx.uploads.shutdown()
            if (exports := getattr(app.state, "exports", None)) is not None:
                exports.shutdown()  # the report exports' worker (server/routes/reports.py)
            if ctx.leg_view is not None:
                ctx.leg_view.close()
            store.close()

    app = FastAPI(
        title="gaitscope",
        version=gaitscope_version(),
        description="Gait-state estimation dashboard for powered exoskeletons and prostheses.",
        lifespan=lifespan,
        openapi_url=None,  # served by _api_docs behind the read permission instead
        docs_url=None,
        redoc_url=None,
    )
    app.add_middleware(SameOriginMiddleware)
    app.add_middleware(AuditMiddleware)  # inside the host check: records the same-origin rule's 403s too
    app.add_middleware(AllowedHostsMiddleware, allowed_hosts=settings.allowed_hosts)
    app.add_middleware(ServerSendMiddleware)  # outermost: keeps the server's own send (server/ws_close.py)
    install_error_handlers(app)
    for router in ROUTERS:
        app.include_router(router)
    _api_docs(app)
    if WEB_DIR.is_dir():
        app.mount("/", StaticFiles(directory=WEB_DIR, html=True), name="web")
    return app
