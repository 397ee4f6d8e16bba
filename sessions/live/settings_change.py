"""A clinician's settings change in a running session: checked, stored, and only then applied.

A change is checked against the settings in effect (bounds by the schema, rates of change by
:data:`~gaitscope.sessions.schema.SETTING_LIMITS`, a switch of the primary at most once per
:data:`~gaitscope.sessions.schema.PRIMARY_SWITCH_INTERVAL_S`, and the rule for changes that can raise the torque
on the person, :mod:`gaitscope.sessions.live.torque_rule`: confirmed, with the peak torque before and after, at
most one every :data:`~gaitscope.sessions.schema.TORQUE_RAISE_INTERVAL_S`; lowering the torque gain, the maximum
torque or the intent boost is never held back by a rate), stored with its events in one transaction by the
database writer, and applied only then (the estimator retuned, the settings and events recorded and sent), so
that what runs is always what the database and the rate limits say. While it is being stored the session's
samples wait for it (:meth:`SettingsChanges.applied`), so that it applies at the sample its events name.
The times of the rate limits are the session's injected clock.
"""

from __future__ import annotations

import asyncio
import functools
import logging
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from gaitscope.sessions import schema
from gaitscope.sessions.live.extensions import describe
from gaitscope.sessions.live.torque_rule import RAISING, GaitState, TorqueRaise, assess, raising_fields, refusal
from gaitscope.sessions.registry import DECLARED
from gaitscope.sessions.schema import SessionSettings, SettingsChange
from gaitscope.sessions.stack import OWN_TORQUE
from gaitscope.sessions.store_writer import Write

if TYPE_CHECKING:
    from gaitscope.sessions.live.runtime import SessionRuntime

__all__ = ["ChangeNotSaved", "SettingRejected", "SettingsChanges", "TorqueRaiseRejected", "change_words"]

log = logging.getLogger("gaitscope")

_Stored = tuple[schema.Session, list[schema.Event]]


class SettingRejected(ValueError):
    """A settings change that breaks a rate-of-change limit; the message says which and why."""


class TorqueRaiseRejected(SettingRejected):
    """A change that can raise the torque, refused by :mod:`~gaitscope.sessions.live.torque_rule` (not confirmed,
    or too soon after the last): :attr:`detail` names the peak torque before and after (the 409's body)."""

    def __init__(self, detail: schema.TorqueRaiseRefused):
        super().__init__(detail.message)
        self.detail = detail


class ChangeNotSaved(RuntimeError):
    """A change that could not be stored, and so was not applied; the message says why."""


@dataclass(frozen=True)
class _Plan:
    """A checked settings change waiting to be stored: the new settings, the fields that change, their
    events (``Store.add_event`` arguments), the session time and the clock's time of the change."""

    new: SessionSettings
    fields: list[str]
    events: list[dict[str, Any]]
    t: float
    now: float
    raises: TorqueRaise | None = None


class SettingsChanges:
    """The settings changes of one session (see the module docstring).

    Attributes:
        saving: a change is being stored: the session's samples wait for it, another change is refused.
    """

    def __init__(self, runtime: SessionRuntime):
        self.rt = runtime
        self.saving = False
        self._last_change: dict[str, float] = {}
        self._last_raise: float | None = None  # the clock's time of the last change that could raise the torque
        self._applied = asyncio.Event()

    def change(self, change: SettingsChange) -> schema.Session:
        """Check, store (this thread waits for the writer) and apply ``change``.

        Raises:
            SettingRejected: a rate-of-change limit, or another change still being stored; nothing changed.
            ChangeNotSaved: the database refused the write; nothing changed.
        """
        begun = self._begin(change, notify=False)
        if begun is None:
            return self.rt.session
        plan, write = begun
        try:
            stored: _Stored | Exception = write.result()
        except Exception as e:
            stored = e
        return self._finish(plan, stored, notify=False)

    async def change_async(self, change: SettingsChange) -> schema.Session:
        """:meth:`change` for a coroutine on the session's loop: the samples of the other sessions go on while
        the writer stores the change. A caller cancelled meanwhile does not undo it: the change, stored, is
        applied when the write completes.

        Raises: as :meth:`change`.
        """
        begun = self._begin(change, notify=True)
        if begun is None:
            return self.rt.session
        plan, write = begun
        future = write.future
        assert future is not None  # submitted from this loop
        try:
            stored: _Stored | Exception = await asyncio.shield(future)
        except asyncio.CancelledError:
            future.add_done_callback(lambda f: self._stored_late(plan, f))
            raise
        except Exception as e:
            stored = e
        return self._finish(plan, stored, notify=True)

    async def applied(self) -> None:
        """Wait until the settings change being stored is applied (or refused)."""
        while self.saving:
            await self._applied.wait()

    def _begin(self, change: SettingsChange, notify: bool) -> tuple[_Plan, Write[_Stored]] | None:
        """Check the change and submit its write (None: nothing changes); the session is then saving.
        ``notify``: the loop's samples wait on :meth:`applied` (a coroutine's change)."""
        plan = self._plan(change)
        if plan is None:
            return None
        rt = self.rt
        write = functools.partial(
            rt.store.change_settings, rt.session.id, plan.new, plan.events, trial_id=rt.trial.id if rt.trial else None
        )
        try:
            submitted = rt.writer.submit(write, f"session {rt.session.id}: settings change")
        except Exception as e:  # the writer is closed
            raise self._not_saved(e) from e
        self.saving = True
        if notify:
            self._applied.clear()
        return plan, submitted

    def _finish(self, plan: _Plan, stored: _Stored | Exception, notify: bool) -> schema.Session:
        """The write is done: the events stored before it are recorded and sent first, then the change is
        applied if it was stored; the session's samples go on."""
        try:
            self.rt.settle_events()
            if isinstance(stored, Exception):
                raise self._not_saved(stored) from stored
            return self._apply(plan, stored)
        finally:
            self._done(notify)

    def _not_saved(self, e: Exception) -> ChangeNotSaved:
        log.error("session %d: settings change not saved: %s", self.rt.session.id, e)
        return ChangeNotSaved(f"the change could not be saved ({describe(e)}), so it was not applied")

    def _stored_late(self, plan: _Plan, future: asyncio.Future[Any]) -> None:
        """A change whose caller was cancelled while it was being stored: applied if it was stored."""
        try:
            self.rt.settle_events()
            if not future.cancelled() and future.exception() is None:
                self._apply(plan, future.result())
        finally:
            self._done(notify=True)

    def _done(self, notify: bool) -> None:
        self.saving = False
        if notify:
            self._applied.set()

    def _apply(self, plan: _Plan, stored: _Stored) -> schema.Session:
        """Apply a stored change: the estimator retuned, the settings and their events recorded and sent."""
        rt = self.rt
        session, events = stored
        rt.session = session
        rt.estimator.retune(plan.new)
        for name in plan.fields:
            self._last_change[name] = plan.now
        if plan.raises is not None:
            self._last_raise = plan.now

        def write(recorder: Any) -> None:
            recorder.write("/settings", plan.t, plan.new)
            for event in events:
                recorder.write_event(event)

        rt.write_recording(write)
        rt.broadcast(schema.SettingsMessage(session_id=session.id, settings=plan.new))
        for event in events:
            rt.broadcast(schema.EventMessage(event=event))
        return session

    def _plan(self, change: SettingsChange) -> _Plan | None:
        """The new settings and their events, checked against the limits (None: nothing changes).

        Raises:
            SettingRejected: why not; nothing changed (:class:`TorqueRaiseRejected`: the torque rule's refusal).
        """
        if self.saving:
            raise SettingRejected("another settings change is being saved; try again in a moment")
        current = self.rt.session.settings
        updates = self._updates(change)
        now = self.rt.clock()
        for name, value in updates.items():
            if name == "primary":
                self._check_primary(value, now)
                continue
            if name in RAISING and value < getattr(current, name):
                continue  # lowering the torque is never held back (safety: it must always be possible)
            _, _, per_second = schema.SETTING_LIMITS[name]
            step = abs(value - getattr(current, name))
            if step > per_second + 1e-12:
                raise SettingRejected(
                    f"{name} may change by at most {per_second:g} per step and per second; "
                    f"{getattr(current, name):g} -> {value:g} is a step of {step:g}"
                )
            last = self._last_change.get(name)
            if last is not None and now - last < step / per_second:
                wait = step / per_second - (now - last)
                raise SettingRejected(
                    f"{name} changed {now - last:.2f} s ago; a step of {step:g} needs "
                    f"{step / per_second:.2f} s between changes (try again in {wait:.2f} s)"
                )
        if not updates:
            return None
        new = current.model_copy(update=updates)
        raises = self._torque_rule(change, current, new, updates, now)
        t, reason = self.rt.estimator.last_t, change.reason
        events = [
            {
                "t": t,
                "kind": "setting",
                "text": change_words(name, getattr(current, name), value)
                + (f", the torque blends over {self.rt.estimator.stack.blend_s:g} s" if name == "primary" else "")
                + (f" ({reason})" if reason else ""),
                "field": name,
                "before": getattr(current, name),
                "after": value,
                "actor": change.actor,
            }
            for name, value in updates.items()
        ]
        return _Plan(new, list(updates), events, t, now, raises)

    def _updates(self, change: SettingsChange) -> dict[str, Any]:
        """The fields ``change`` sets to another value than the settings in effect."""
        current = self.rt.session.settings
        asked = change.model_dump(exclude={"actor", "reason", "confirm"}).items()
        return {k: v for k, v in asked if v is not None and v != getattr(current, k)}

    def check(self, change: SettingsChange) -> schema.TorqueCheck:
        """What ``change`` would do to the torque (the peaks before and after, whether it asks, how long until it
        may be made), changing nothing: for a client to ask its user first. The bounds and rates are not checked."""
        current = self.rt.session.settings
        updates = self._updates(change)
        new = current.model_copy(update=updates)
        fields = raising_fields(current, updates)
        stack = self.rt.estimator.stack
        before = self._gait_state(stack.primary)
        after = self._gait_state(new.primary) if "primary" in fields else before
        peaks = assess(current, new, fields, before, after, stack.mass_kg)
        wait = 0.0
        if fields and self._last_raise is not None:
            wait = max(0.0, schema.TORQUE_RAISE_INTERVAL_S - (self.rt.clock() - self._last_raise))
        return schema.TorqueCheck(
            fields=fields, peak_before_Nm=peaks.peak_before_Nm, peak_after_Nm=peaks.peak_after_Nm, retry_after_s=wait
        )

    def _torque_rule(
        self,
        change: SettingsChange,
        current: SessionSettings,
        new: SessionSettings,
        updates: dict[str, Any],
        now: float,
    ) -> TorqueRaise | None:
        """The torque rule (:mod:`~gaitscope.sessions.live.torque_rule`) for a change: None if it cannot raise
        the torque, else its peaks, when it may be made.

        Raises:
            TorqueRaiseRejected: not confirmed, or too soon after the last change that could raise the torque.
        """
        fields = raising_fields(current, updates)
        if not fields:
            return None
        stack = self.rt.estimator.stack
        before = self._gait_state(stack.primary)
        after = self._gait_state(new.primary) if "primary" in fields else before
        raises = assess(current, new, fields, before, after, stack.mass_kg)
        refused = refusal(raises, change.confirm, now, self._last_raise, schema.TORQUE_RAISE_INTERVAL_S)
        if refused is not None:
            raise TorqueRaiseRejected(refused)
        return raises

    def _gait_state(self, primary: str | None) -> GaitState:
        """The gait state the peak torque of ``primary`` is computed at: its last stride length and incline, the
        nominal ones where it has none (:mod:`gaitscope.sessions.peak_torque`)."""
        stack = self.rt.estimator.stack
        if primary is None or primary not in stack.names:
            return GaitState(None, math.nan, math.nan, commands=False)  # nothing drives the torque: 0
        k = stack.names.index(primary)
        outputs = stack.outputs[k]
        profile = None if OWN_TORQUE in outputs else stack.torque
        last = self.rt.estimator.last
        y = None if last is None else last.outputs[k]

        def value(name: str) -> float:
            return math.nan if y is None or name not in outputs else float(y[outputs.index(name)])

        return GaitState(profile, value("stride_length_m") / stack.leg_length, value("incline_deg"))

    def _check_primary(self, name: str, now: float) -> None:
        """A switch of the primary: to an estimator of the stack that estimates a phase and has not failed,
        at most once per ``PRIMARY_SWITCH_INTERVAL_S``.

        Raises:
            SettingRejected: why not; nothing changed.
        """
        try:
            self.rt.estimator.stack.check_primary(name)
        except ValueError as e:
            raise SettingRejected(f"primary {name}: {e}") from e
        last = self._last_change.get("primary")
        interval = schema.PRIMARY_SWITCH_INTERVAL_S
        if last is not None and now - last < interval:
            raise SettingRejected(
                f"primary changed {now - last:.2f} s ago; switches are at least {interval:g} s apart "
                f"(try again in {interval - (now - last):.2f} s)"
            )


def change_words(name: str, before: object, after: object) -> str:
    """A setting's change in an event's text, in the screen's words (issue #23: one vocabulary): the setting's
    name and unit from :data:`~gaitscope.sessions.schema.SETTING_NAMES`, an estimator by its label, numbers as
    ``%g`` ("Maximum torque 30 N·m → 35 N·m", "Torque follows Phase EKF (seed 000) → Timing-based estimate")."""
    label, unit = schema.SETTING_NAMES.get(name, (name, ""))
    return f"{label} {_shown(name, before, unit)} → {_shown(name, after, unit)}"


def _shown(name: str, value: object, unit: str) -> str:
    if name == "primary" and isinstance(value, str) and value in DECLARED:
        return DECLARED[value].label
    if not isinstance(value, float):
        return str(value)
    if unit == "×":
        return f"{value:g}×"
    return f"{value:g} {unit}" if unit in ("N·m", "m/s", "deg") else f"{value:g}"
