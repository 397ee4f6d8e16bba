"""Undo a running session's last applied settings change, as a change of its own (bounded, rate-limited, logged)."""

from __future__ import annotations

from collections.abc import Callable

from gaitscope.sessions import schema
from gaitscope.sessions.live.runtime import SessionRuntime, SettingRejected
from gaitscope.sessions.live.settings_change import change_words

#: The fields a settings change may set (and so an undo may set back).
UNDOABLE = (*schema.SETTING_LIMITS, "primary")


def last_change(events: list[schema.Event]) -> list[schema.Event]:
    """The events of the newest settings change (one per field it changed), oldest first; [] if none.

    One change is the run of setting events stored together (``Store.change_settings`` writes them in one
    transaction): consecutive ids, the same session time and the same actor (their wall-clock stamps may
    differ by a millisecond). ``events`` oldest first, as ``Store.list_events`` returns them.
    """
    changes = [e for e in events if e.kind == "setting" and e.field in UNDOABLE]
    if not changes:
        return []
    group = [changes[-1]]
    for e in reversed(changes[:-1]):
        first = group[0]
        if (e.id, e.t, e.actor) != (first.id - 1, first.t, first.actor):
            break
        group.insert(0, e)
    return group


def undo_change(
    runtime: SessionRuntime, events: list[schema.Event], actor: str, confirm: bool = False
) -> schema.SettingsChange:
    """The settings change that sets the fields of the newest change back to their values before it.

    The undo is a settings change like any other (``SessionRuntime.change_settings`` or its async twin): the
    same bounds and rate limits, the same rule for a change that can raise the torque (``confirm``, the user's
    confirmation of it; :mod:`gaitscope.sessions.live.torque_rule`), and one setting event per field, its text
    saying which change it undid.

    Raises:
        SettingRejected: nothing to undo, or a field has changed since by other means (the primary after a
            failure); nothing changed.
    """
    group = last_change(events)
    if not group:
        raise SettingRejected("nothing to undo: no setting has been changed in this session")
    current = runtime.session.settings
    for e in group:
        assert e.field is not None
        now = getattr(current, e.field)
        if now != e.after:
            raise SettingRejected(
                f"the last change cannot be undone: {e.field} is now {now}, not the {e.after} it set "
                "(it has changed since)"
            )
    undone = ", ".join(change_words(e.field, e.before, e.after) for e in group if e.field)
    return schema.SettingsChange.model_validate(
        {
            **{e.field: e.before for e in group if e.field},
            "actor": actor,
            "reason": f"undo of {undone} by {group[0].actor}"[:500],
            "confirm": confirm,
        }
    )


async def undo_last_change(
    runtime: SessionRuntime,
    events: list[schema.Event],
    actor: str,
    check: Callable[[schema.SettingsChange], None] | None = None,
    confirm: bool = False,
) -> schema.Session:
    """Undo the newest settings change (:func:`undo_change`), stored while the event loop runs on
    (``SessionRuntime.change_settings_async``). ``check``, when given, sees the change first and may refuse it
    by raising (the caller's rights, its audit entry). ``confirm``: the user confirmed an undo that can raise the
    torque (without it such an undo is refused with the peaks before and after, ``TorqueRaiseRejected``).

    Raises:
        SettingRejected: as :func:`undo_change`, or a rate limit (the message says how long to wait), or the
            torque rule; nothing changed.
    """
    change = undo_change(runtime, events, actor, confirm)
    if check is not None:
        check(change)
    return await runtime.change_settings_async(change)
