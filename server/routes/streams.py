"""Websockets: live streams to browsers and the live-device ingest. Protocol in ``docs/api.md``.

A browser's stream opens with the session's recent history (:class:`~sessions.live.subscribers.SessionHistory`,
the last 30 s, as ordinary state batches right after the hello), so its plots are never empty. The live view's
one REST action that belongs with its stream, undoing the last settings change, is here too.

Every message sent is a class of :mod:`gaitscope.sessions.schema` (``BrowserMessage`` to browsers,
``DeviceMessage`` to devices), serialised by :func:`_dump`, so that ``GET /api/schema`` and the
browser's ``web/wire.js`` describe each one.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Annotated

from fastapi import APIRouter, Query, WebSocket, WebSocketDisconnect
from pydantic import ValidationError
from starlette.types import Message

from gaitscope.server.auth import Assistant, Who, allow, device
from gaitscope.server.routes.common import Ctx, Id, audit, check_assistance, not_running_here
from gaitscope.server.ws_close import close_stuck
from gaitscope.sessions import schema
from gaitscope.sessions.estimation import FrameRefused
from gaitscope.sessions.live.manager import SessionStateError
from gaitscope.sessions.live.runtime import SessionRuntime, Subscriber
from gaitscope.sessions.live.sources import CONNECT_S, RECEIVE_S, LiveDevice, frame_refusal, invalid_notice
from gaitscope.sessions.live.subscribers import SessionHistory, attach_history
from gaitscope.sessions.live.undo import undo_last_change
from gaitscope.sessions.store import NotFound

if TYPE_CHECKING:
    from gaitscope.server.app import AppContext

log = logging.getLogger("gaitscope")
router = APIRouter()

#: Close codes.
NOT_FOUND, POLICY, TRY_AGAIN = 4404, 1008, 1013
#: A device that sends this many malformed frames in a row is disconnected.
MAX_BAD_FRAMES = 50

#: What a session stream sends a browser, and what the ingest sends a device.
BrowserMessage = schema.Hello | schema.StreamBatch | schema.Health | schema.EventMessage | schema.SettingsMessage
DeviceMessage = schema.TorqueCommand | schema.DeviceNotice


def _clients(runtime: SessionRuntime) -> int:
    """Browsers streaming the session (its history is no client)."""
    return sum(1 for s in runtime.subscribers if not isinstance(s, SessionHistory))


def _dump(message: BrowserMessage | DeviceMessage) -> str:
    """The JSON text of a schema message: the only thing a socket here sends."""
    return message.model_dump_json()


async def _runtime(ws: WebSocket, session_id: int) -> SessionRuntime | None:
    c: AppContext = ws.app.state.ctx
    runtime = c.manager.get(session_id)
    if runtime is None:
        try:
            c.store.get_session(session_id)
            reason = not_running_here(c, session_id)
        except NotFound:
            reason = f"session {session_id} does not exist"
        await ws.close(code=NOT_FOUND, reason=reason[:120])
        return None
    return runtime


@router.websocket("/ws/sessions/{session_id}", dependencies=[allow("read")])
async def session_stream(
    ws: WebSocket,
    session_id: Id,
    max_rate_hz: float = Query(default=60.0, ge=0.0, le=2000.0),
    batch_ms: float = Query(default=33.0, ge=0.0, le=1000.0),
) -> None:
    """Stream a session's gait states (decimated and batched as the client asks), health and events.

    Closed with 1008 and the reason within moments of the login it was opened with ending (logout, the
    account disabled or demoted, its password changed), as a device's stream is when its token is revoked."""
    await ws.accept()
    runtime = await _runtime(ws, session_id)
    if runtime is None:
        return
    login_ended = _login_ended(ws)
    history = attach_history(runtime)
    sub = runtime.subscribe(max_rate_hz)
    history.seam(sub)
    recent = history.batches(session_id)  # with the subscription, before any await: no sample in both, none lost
    try:
        hello = schema.Hello(session=runtime.session, subject=runtime.subject, source_rate_hz=runtime.source.rate_hz)
        await ws.send_text(_dump(hello))
        for batch in recent:
            await ws.send_text(_dump(batch))
        ended = asyncio.create_task(login_ended.wait())
        pump, drain = asyncio.create_task(_pump(ws, runtime, sub, batch_ms / 1000.0)), asyncio.create_task(_drain(ws))
        tasks = {pump, drain, ended}
        _, pending = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        for task in pending:
            task.cancel()
        for task in tasks:
            with contextlib.suppress(asyncio.CancelledError, WebSocketDisconnect, RuntimeError):
                await task
        if ended.done() and not ended.cancelled():
            with contextlib.suppress(Exception):
                await asyncio.wait_for(ws.close(code=POLICY, reason=ended.result()[:120]), timeout=1.0)
    except (WebSocketDisconnect, RuntimeError):
        pass
    finally:
        runtime.unsubscribe(sub)
        login_ended.close()


#: Seconds between a stream's checks that its login is still open in the database: the fallback for logins
#: ended where this process cannot see it (another process, ``gaitscope user reset-password``; expiry).
LOGIN_CHECK_S = 10.0


class _LoginEnded:
    """Tells a socket that the login it was opened with has ended: at once when this process ends it
    (:class:`~gaitscope.sessions.accounts.LoginWatch`), within :data:`LOGIN_CHECK_S` otherwise."""

    def __init__(self, ws: WebSocket, who: Who | None) -> None:
        self._c: AppContext = ws.app.state.ctx
        self._login_id = None if who is None else who.login_id
        self._reason: asyncio.Future[str] = asyncio.get_running_loop().create_future()
        self._unwatch: Callable[[], None] | None = None
        if self._login_id is not None:
            loop = asyncio.get_running_loop()
            self._unwatch = self._c.accounts.watch.watch(
                self._login_id, lambda reason: loop.call_soon_threadsafe(self._set, reason)
            )

    def _set(self, reason: str) -> None:
        if not self._reason.done():
            self._reason.set_result(reason)

    async def wait(self) -> str:
        """The reason, once the login has ended (never, with accounts off). Asks the database at once too:
        the login may have ended between the socket's check and its watch."""
        login_id = self._login_id
        while login_id is not None:
            if login_id not in await asyncio.to_thread(self._c.accounts.open_logins, [login_id]):
                self._set("login ended")
            with contextlib.suppress(TimeoutError):
                return await asyncio.wait_for(asyncio.shield(self._reason), timeout=LOGIN_CHECK_S)
        return await self._reason

    def close(self) -> None:
        if self._unwatch is not None:
            self._unwatch()


def _login_ended(ws: WebSocket) -> _LoginEnded:
    who = ws.scope.get("gaitscope.who")
    return _LoginEnded(ws, who if isinstance(who, Who) else None)


async def _drain(ws: WebSocket) -> None:
    """Read (and ignore) what the browser sends, so a disconnect is noticed at once."""
    while True:
        await ws.receive_text()


class _SlowClient(Exception):
    pass


async def _pump(ws: WebSocket, runtime: SessionRuntime, sub: Subscriber, batch_s: float) -> None:
    """Send what the runtime left for this client; never holds the runtime up.

    A send that cannot complete (the client stopped reading and the socket buffers are full) or a client
    that keeps losing samples for ``slow_client_s`` is closed with 1013; the runtime meanwhile only
    appends to the subscriber's bounded buffer.
    """
    limit = ws.app.state.ctx.settings.slow_client_s
    behind_since: float | None = None
    last_dropped = 0

    async def send(message: BrowserMessage) -> None:
        try:
            await asyncio.wait_for(ws.send_text(_dump(message)), timeout=limit)
        except TimeoutError:
            raise _SlowClient(f"client too slow: a send took over {limit:g} s, {sub.dropped} samples dropped") from None

    try:
        while True:
            await sub.wake.wait()
            sub.wake.clear()
            if batch_s > 0:
                await asyncio.sleep(batch_s)
            while sub.messages:
                message = sub.messages.popleft()
                assert isinstance(message, BrowserMessage), f"not a browser message: {type(message).__name__}"
                if isinstance(message, schema.Health):
                    message = message.model_copy(update={"clients": _clients(runtime)})
                await send(message)
            if sub.pending:
                await send(sub.batch(runtime.session.id))  # the states, and every estimator's outputs
            if sub.closed:
                await ws.close(code=1000, reason=f"session {runtime.session.id} stopped")
                return
            if sub.dropped > last_dropped:
                behind_since = behind_since or time.monotonic()
                if time.monotonic() - behind_since > limit:
                    raise _SlowClient(f"client too slow: {sub.dropped} samples dropped")
            else:
                behind_since = None
            last_dropped = sub.dropped
    except _SlowClient as e:
        runtime.unsubscribe(sub)
        # a client that stopped reading has filled the buffers: the close goes past them (gaitscope.server.ws_close), or
        # the connection would end later in a keepalive timeout's 1011 instead
        await close_stuck(ws, TRY_AGAIN, str(e))


@router.post("/api/sessions/{session_id}/settings/undo")
async def undo_settings(session_id: Id, body: schema.SettingsUndo, c: Ctx, who: Assistant) -> schema.Session:
    """Undo the session's last applied settings change (409 with the reason when it cannot be, now; an undo that can
    raise the torque on the person needs ``confirm``, as a settings change does)."""
    runtime = c.manager.get(session_id)
    if runtime is None:
        c.store.get_session(session_id)  # 404 for an unknown session
        raise SessionStateError(not_running_here(c, session_id, "; settings change only while it runs"))
    subject_id = runtime.session.subject_id

    def check(change: schema.SettingsChange) -> None:
        requested = change.model_dump(exclude={"actor", "reason", "confirm"}, exclude_none=True)
        check_assistance(c, who, subject_id, requested)
        current = runtime.session.settings.model_dump()
        before = {k: current[k] for k in requested}
        after = {**requested, "confirm": True} if change.confirm else requested
        audit(c, who, "settings.undo", f"session {session_id}", before=before, after=after, detail=change.reason)

    events = await asyncio.to_thread(c.store.list_events, session_id)  # a read off the loop, as the write is
    # an undo that can raise the torque is held to the torque rule as any change: confirmed (body.confirm), rate-limited
    return await undo_last_change(runtime, events, who.name, check=check, confirm=body.confirm)


@router.websocket("/ws/devices/{session_id}")
async def device_ingest(ws: WebSocket, session_id: Id, token_id: Annotated[int, device()]) -> None:
    """A live device: ``SensorFrame`` in, ``TorqueCommand`` out, one for one.

    A frame that is refused gets a short :class:`~gaitscope.sessions.schema.DeviceNotice` instead of a torque:
    malformed, binary, too large (refused unparsed), reordered, or over the session's declared rate
    (those are dropped before they are parsed, and reported at most once a second). A message over the
    server's ``ws_max_kb`` never gets here: the websocket closes with 1009. What the device's messages
    cost the event loop is held to its share (:class:`~gaitscope.sessions.live.sources.DeviceBudget`): past it, its
    socket is read late; held back for seconds on end for messages that were refused, the device is
    disconnected (1008), as it is after :data:`MAX_BAD_FRAMES` malformed frames in a row. A device that reconnects
    (after a reboot, its clock restarted) is resynchronised. An error while processing a frame fails the
    session, with an event, and closes the socket with 1011.
    """
    await _connect_turn(ws, session_id)
    await ws.accept()
    runtime = await _runtime(ws, session_id)
    if runtime is None:
        return
    source = runtime.source
    if not isinstance(source, LiveDevice):
        await ws.close(
            code=POLICY, reason=f"session {session_id} takes no device (source {runtime.session.source.kind})"
        )
        return
    if source.connected:
        await ws.close(code=POLICY, reason=f"session {session_id} already has a device connected")
        return
    source.connected = True
    runtime.device_connected()
    ingest = _Ingest(ws, runtime, source)
    budget = source.budget
    try:
        while True:
            pause = budget.pause()
            if pause is not None:
                if budget.exhausted:
                    reason = f"refused messages over its share of the server ({budget.share:.0%}) for "
                    await ws.close(code=POLICY, reason=f"session {session_id}: {reason}{budget.close_after_s:g} s")
                    return
                await asyncio.sleep(pause)  # a turn for the other sessions; longer while over its share
            message = await ws.receive()
            if message["type"] == "websocket.disconnect":
                return
            if source.closed or runtime.ended is not None:
                await ws.close(code=1000, reason=f"session {session_id} {runtime.ended or 'stopped'}"[:120])
                return
            if token_id in source.revoked:
                await ws.close(code=POLICY, reason=f"session {session_id}: this device's token was revoked")
                return
            started = time.thread_time()
            close = await ingest.take(message)
            budget.charge(time.thread_time() - started + RECEIVE_S, refused=ingest.refused)
            if close is not None:
                await ws.close(code=close[0], reason=close[1][:120])
                return
    except (WebSocketDisconnect, RuntimeError):
        pass
    finally:
        source.connected = False
        with contextlib.suppress(Exception):
            await ws.close()


async def _connect_turn(ws: WebSocket, session_id: int) -> None:
    """Charge a connection to the session's device budget, and hold its handshake while the device is over
    its share: a device that reconnects at once after each close cannot spend more than its share that way."""
    runtime = ws.app.state.ctx.manager.get(session_id)
    if runtime is not None and isinstance(runtime.source, LiveDevice):
        budget = runtime.source.budget
        budget.charge(CONNECT_S)
        pause = budget.pause()
        if pause:
            await asyncio.sleep(pause)


class _Ingest:
    """One device connection's messages, one at a time: admitted, parsed, processed and answered."""

    def __init__(self, ws: WebSocket, runtime: SessionRuntime, source: LiveDevice):
        self.ws, self.runtime, self.source = ws, runtime, source
        self.bad = 0  # malformed frames in a row
        self.over_rate = 0  # frames dropped over the rate since the last rate notice
        self.last_rate_notice = -math.inf
        self.refused = False  # the last message taken was refused (dropped, malformed, out of order)

    async def _notice(self, notice: schema.DeviceNotice) -> None:
        self.refused = True
        await self.ws.send_text(_dump(notice))

    async def take(self, message: Message) -> tuple[int, str] | None:
        """Answer one message; the close code and reason when the socket must close."""
        self.refused = False
        recv = time.time_ns()
        now = time.monotonic()
        source, runtime = self.source, self.runtime
        if not source.admit(now):
            self.refused = True
            self.over_rate += 1
            if now - self.last_rate_notice >= 1.0:
                self.last_rate_notice = now
                detail = f"over the declared rate of {source.rate_hz:g} Hz: {self.over_rate} frames dropped"
                await self._notice(schema.DeviceNotice(kind="rate", detail=detail, dropped=self.over_rate))
                self.over_rate = 0
            return None
        frame = _parse(message.get("text"))
        if isinstance(frame, schema.DeviceNotice):
            self.bad += 1
            runtime.dropped_input += 1
            await self._notice(frame)
            return (POLICY, f"{self.bad} malformed frames in a row") if self.bad >= MAX_BAD_FRAMES else None
        self.bad = 0
        if runtime.settings_changes.saving:  # its settings change is being stored: it applies first (the others go on)
            await runtime.settings_changes.applied()
        try:
            runtime.process(frame, recv)
        except FrameRefused as e:
            runtime.dropped_input += 1
            await self._notice(schema.DeviceNotice(kind="order", detail=str(e), seq=frame.seq))
            return None
        except Exception as e:
            session_id = runtime.session.id
            log.exception("session %d: processing a device frame failed", session_id)
            await runtime.end("failed", f"processing a device frame failed: {e}")
            return 1011, f"session {session_id} failed"
        await self.ws.send_text(runtime.last_command)  # the TorqueCommand of this frame, as recorded
        return None


def _parse(text: str | None) -> schema.SensorFrame | schema.DeviceNotice:
    """The frame in a message's text, or the notice that refuses it: binary, too large (unparsed), invalid."""
    if text is None:
        return schema.DeviceNotice(kind="binary", detail="binary message: frames are JSON text")
    refusal = frame_refusal(text)
    if refusal is not None:
        return refusal
    try:
        return schema.SensorFrame.model_validate_json(text)
    except ValidationError as e:
        return invalid_notice(e)
