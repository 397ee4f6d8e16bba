"""The GP-EKF's online learning in a session, as a session extension.

The learning itself (windows, fits in the shared worker, acceptance, freeze and rollback) is
:class:`~gaitscope.sessions.live.gp_learning.GPLearning`'s; this extension ties it to the session: it polls the
learning after each recorded sample, records each model record (``/gp_models``) and makes each note an event
(field ``gp_ekf``, stored without making the sample wait), writes the models kept from before a trial at its
start (a re-run starts from them), and takes the clinician's freeze, unfreeze and rollback
(:meth:`GPLearningExtension.control`: stored first, applied only then).
"""

from __future__ import annotations

import asyncio
import contextlib

from gaitscope.sessions import schema
from gaitscope.sessions.formats.recording import Recorder
from gaitscope.sessions.live.extensions import SessionExtension, SessionHost
from gaitscope.sessions.live.gp_learning import GPLearning, GPTrainer, Note
from gaitscope.sessions.live.settings_change import ChangeNotSaved

__all__ = ["GPLearningExtension"]


class GPLearningExtension(SessionExtension):
    """A session's GP-EKF learning (only for a stack that runs ``gp_ekf``: :meth:`of`).

    Args:
        host: the session.
        learning: the stack's GP-EKF learning.
        own_trainer: the session started its worker (and shuts it down when it stops).
    """

    def __init__(self, host: SessionHost, learning: GPLearning, own_trainer: bool):
        self.host = host
        self.learning = learning
        self._own_trainer = own_trainer

    @classmethod
    def of(cls, host: SessionHost, trainer: GPTrainer | None) -> GPLearningExtension | None:
        """The extension for ``host``'s stack (None: it runs no GP-EKF); ``trainer``: the shared worker (None:
        the session's own)."""
        learning = GPLearning.of(host.estimator.stack, trainer or GPTrainer())
        return None if learning is None else cls(host, learning, trainer is None)

    def on_trial(self, recorder: Recorder, t: float) -> None:
        for record in self.learning.kept_records(t):  # the GP models its GP-EKF keeps from before the trial
            recorder.write("/gp_models", t, record)

    def after_record(self, frame: schema.SensorFrame, t: float) -> None:
        for note in self.learning.poll(t):
            self.host.record("/gp_models", note.record)
            if note.text:
                self.host.event_soon(note.kind, note.text, **_fields(note))

    async def stop(self) -> None:
        self.learning.close()
        if self._own_trainer:
            with contextlib.suppress(Exception):
                await asyncio.to_thread(self.learning.trainer.shutdown)

    def control(self, control: schema.GPLearningControl) -> schema.GPLearningState:
        """Freeze, unfreeze or roll back the learning (the caller checked that the GP-EKF runs): logged with
        the actor and stored first, applied only then (at the next heel strike for a rollback), recorded.

        Raises:
            gaitscope.sessions.live.gp_learning.LearningRefused: a rollback to a version not kept; nothing changed.
            ChangeNotSaved: the event could not be stored; nothing changed.
        """
        learning = self.learning
        note = learning.plan(control, self.host.estimator.last_t)
        if note is not None:
            if self.host.event(note.kind, note.text, **_fields(note)) is None:
                raise ChangeNotSaved("the change could not be saved, so it was not applied")
            learning.apply(control)
            self.host.record("/gp_models", note.record)
        return learning.state(self.host.session.id)


def _fields(note: Note) -> dict[str, object]:
    """A learning note's event fields."""
    return {"field": "gp_ekf", "before": note.before, "after": note.after, "actor": note.record.actor}
