"""Seed 003's GP-EKF learning the wearer in a live session (issue #11): background fits, installs at heel
strikes, freeze and rollback, each one an event and a ``/gp_models`` record.

A session whose stack runs ``gp_ekf`` (:class:`~gaitscope.estimators.gp_ekf_estimator.GPEKFEstimator`) has a
:class:`GPLearning`, which the runtime polls after each sample (:meth:`GPLearning.poll`, between the stack's
step and the next frame, on the session's own event loop):

- a training window the filter offers (every 5 completed stances, :meth:`~GPEKFEstimator.take_window`) goes
  to the server's :class:`GPTrainer`, one worker process shared by every session, so that the sample loop
  never waits for a fit nor shares its GIL with one. One fit per session at a time: a window the filter
  offers meanwhile waits (the filter keeps its newest) and is taken when the fit is back;
- a fit that is back is handed to the filter (:meth:`~GPEKFEstimator.offer`) between two samples, so it
  never races ``step``. The filter checks it on the window's held-out stance and keeps it waiting for the
  next heel strike, where ``step`` installs it atomically, or refuses it;
- an install is noticed after the step it happened in (the filter's ``models`` changed).

Each outcome is a :class:`Note`: a system event in plain words (field ``gp_ekf``) with the training window
(steps and time span) and the fit quality (held-out RMSE per joint), and the record of the version
(:class:`~gaitscope.sessions.schema.GPModelRecord`, its arrays on ``trained`` and ``refused``). A fit that raises,
or a worker that dies, is a note too: the session goes on with the model it has.

The clinician's controls (:meth:`GPLearning.plan` then :meth:`GPLearning.apply`): freeze (no fits, no
installs but a rollback; a fit under way when frozen is refused on its return), unfreeze, and rollback to a
kept version at the next heel strike. :meth:`GPLearning.state` is what the dashboard plots: versions, the
learned mean angles with their +-2 sd band over stance phase.

Worker: a process, not a thread, chosen by measuring both (``docs/api.md``, GP-EKF learning: real servers
on this machine's 2 cores, 200 Hz devices whose stacks run ``gp_ekf``, fits of 5 stances of 0.3-0.4 s every
5-6 s). While a fit ran, a device's round trip (frame to torque) had a p99 of 1.3-1.5 ms with a process and
6-14 ms with a thread (1 session), 2.8 against 12 ms (4 sessions), 7 against 28 ms with the cores
overloaded; the worst 4-10 ms against 11-58 ms. In a thread, GPy's fit (NumPy on small ``n x 25``
matrices: mostly Python) holds the GIL in turns with the sample loop, which waits up to the interpreter's
switch interval (5 ms) each time; in a process the loop is as fast as without retraining. The windows and
the fitted model sets cross the process boundary pickled (60-130 kB each).
"""

from __future__ import annotations

import contextlib
import logging
import math
import multiprocessing
import os
import threading
import time
from concurrent.futures import Executor, Future, ProcessPoolExecutor, ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Final, Literal, TypeAlias

import numpy as np

from gaitscope.estimators.gp import FitOptions
from gaitscope.estimators.gp_ekf_estimator import GPEKFEstimator
from gaitscope.estimators.gp_models import GPModelSet, TrainingWindow, fit_models
from gaitscope.sessions import schema
from gaitscope.sessions.gp_models import GP_EKF, arrays_of, gp_ekf_of, rmse_of, window_text
from gaitscope.sessions.stack import EstimatorStack

__all__ = ["DUTY", "FIT_OPTIONS", "NICE", "GPLearning", "GPTrainer", "LearningRefused", "Note", "fit_window"]

log = logging.getLogger("gaitscope")

#: How a session's fits are made: seed 003's 25 inducing points, the hyperparameters by maximum likelihood.
FIT_OPTIONS: Final = FitOptions()
_BAND_PHASE: Final = np.linspace(0.0, 1.0, schema.GP_BAND_POINTS)
#: The fraction of the fitting worker's time it may spend fitting (:class:`GPTrainer`).
DUTY: Final = 0.25
#: How much lower than the server's the fitting worker's priority is (Unix nice increment, :class:`GPTrainer`).
NICE: Final = 10
#: What a fit gives back: the model set, the wall time and the CPU time the fit took (s).
Fitted: TypeAlias = tuple[GPModelSet, float, float]
_ASK_STALE_S: Final = 1.0  # a session that has not asked for this long (s) loses its place in the queue


def fit_window(window: TrainingWindow, options: FitOptions) -> Fitted:
    """Fit a training window (in the worker): the model set, the wall time the fit took and the CPU time it
    used (s). The CPU time is the worker process's (its BLAS threads included) when the fit runs in a
    process's main thread, as in :class:`GPTrainer`'s process pool, and the fitting thread's otherwise."""
    cpu = time.process_time if threading.current_thread() is threading.main_thread() else time.thread_time
    t0, c0 = time.perf_counter(), cpu()
    models = fit_models(window, options)
    return models, time.perf_counter() - t0, cpu() - c0


def _worker_started(nice: int) -> None:
    """In the worker process, once: import what a fit needs (GPy takes a second or two of a core) before the
    first window comes, then lower the worker's priority by ``nice``.

    The import runs at normal priority, so that a worker niced on a machine whose cores are busy does not
    spend its first minute importing (a precaution: the CI failure that prompted it had another cause, a
    test device that timed out). The fits run niced: a fit
    is a burst of 0.3-0.4 s of one core, and on a machine short of cores it delayed the sample loops and the
    browsers' streams around it (``gaitscope loadbench --gp-ekf``, 10 sessions on 2 cores: p95 64 ms at normal
    priority, 45-53 ms niced to 19, both with :data:`DUTY`). Niced to 19 its fits starved behind any busy
    process (8-20 s a fit instead of 0.4-0.7 s under a CI run; Linux gives a nice-19 process 1.5 % of a core
    that a nice-0 one wants, a nice-10 one 10 %): the default, :data:`NICE`, is 10, and the duty budget bounds
    how much it asks for."""
    import GPy  # noqa: F401

    if nice:
        os.nice(nice)


class GPTrainer:
    """The server's background worker for GP fits, shared by its sessions (the session manager's).

    One fit at a time, and at most ``duty`` of the worker's time spent fitting: after a fit that used ``d``
    seconds of CPU the next starts no sooner than ``d * (1 / duty - 1)`` seconds later. CPU time, not wall
    time: a niced worker on a busy machine waits for the cores, and charging that wait as fitting (a 0.4 s
    fit that took 40 s) stopped a session's learning for minutes. A session asks before
    it submits (:meth:`may_submit`); of the sessions with a window ready, the one that has asked longest
    goes first. Seed 003 retrains every 5 steps; with one session a fit (0.3-0.4 s) every 5 steps is
    about 8 % busy and the budget never binds. With many sessions on few cores it does: each retrains
    less often (its filter keeps its newest window), so that the fits never take the cores the sample
    loops need. Measured with ``gaitscope loadbench --gp-ekf`` (``docs/dashboard.md``): 10 sessions
    fitting back to back kept the worker busy all the time on 2 cores and the devices' p95 latency went
    from 46 ms to 160-1900 ms.

    Args:
        kind: ``process`` (default: a single-worker process pool, started on first use) or ``thread`` (a
            single worker thread: for measuring the difference, see the module docstring).
        options: how the GPs are fitted.
        duty: the fraction of the worker's time it may spend fitting, in (0, 1] (1: back to back).
        nice: the worker process's nice increment after it imported GPy, 0-19 (0: the server's priority; the
            ``thread`` kind ignores it).
    """

    def __init__(
        self,
        kind: Literal["process", "thread"] = "process",
        options: FitOptions = FIT_OPTIONS,
        duty: float = DUTY,
        nice: int = NICE,
    ):
        if kind not in ("process", "thread"):
            raise ValueError(f"kind must be 'process' or 'thread', got {kind!r}")
        if not (math.isfinite(duty) and 0.0 < duty <= 1.0):
            raise ValueError(f"duty must be in (0, 1], got {duty!r}")
        if not 0 <= nice <= 19:
            raise ValueError(f"nice must be in 0..19, got {nice!r}")
        self.kind = kind
        self.options = options
        self.duty = duty
        self.nice = nice
        self._pool: Executor | None = None
        self._lock = threading.Lock()  # the fit's done-callback runs in the pool's thread
        self._in_flight = 0
        self._next_start = 0.0  # time.monotonic() before which no fit starts
        self._asks: dict[int, tuple[float, float]] = {}  # asking session (id) -> (first, last) time it asked

    def may_submit(self, session: object) -> bool:
        """Whether ``session``, which has a window ready, may submit it now (then it must): no fit under way,
        the duty budget allows one, and no session has been asking longer. A session that stopped asking
        (for a second: stopped, frozen, or its window went) loses its place."""
        now = time.monotonic()
        key = id(session)
        self._asks[key] = (self._asks.get(key, (now, now))[0], now)
        with self._lock:
            if self._in_flight or now < self._next_start:
                return False
        self._asks = {k: v for k, v in self._asks.items() if now - v[1] <= _ASK_STALE_S}
        if min(self._asks, key=lambda k: self._asks[k][0]) != key:
            return False
        del self._asks[key]
        return True

    def _track(self, future: Future[Fitted]) -> Future[Fitted]:
        """Count ``future`` as the fit under way until it is done; then set when the next may start (a fit
        that failed is charged its wall time)."""
        submitted = time.monotonic()
        with self._lock:
            self._in_flight += 1

        def done(f: Future[Fitted]) -> None:
            now = time.monotonic()
            fit_s = now - submitted
            if not f.cancelled() and f.exception() is None:
                fit_s = f.result()[2]
            with self._lock:
                self._in_flight -= 1
                self._next_start = max(self._next_start, now + fit_s * (1.0 / self.duty - 1.0))

        future.add_done_callback(done)
        return future

    @property
    def started(self) -> bool:
        return self._pool is not None

    def start(self) -> None:
        """Start the worker (it imports GPy in the background); nothing if it runs."""
        if self._pool is not None:
            return
        if self.kind == "thread":
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="gp-fit")
            return
        method = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
        context = multiprocessing.get_context(method)
        self._pool = ProcessPoolExecutor(
            max_workers=1, mp_context=context, initializer=_worker_started, initargs=(self.nice,)
        )
        self._pool.submit(int)  # start the worker now: it imports GPy while the first window fills

    def submit(self, window: TrainingWindow) -> Future[Fitted]:
        """Fit ``window`` in the worker (:func:`fit_window`). A pool whose worker died (its fits failed with
        ``BrokenProcessPool``) is replaced here, once, whichever session submits next."""
        self.start()
        assert self._pool is not None
        try:
            return self._track(self._pool.submit(fit_window, window, self.options))
        except BrokenProcessPool:
            pool, self._pool = self._pool, None
            with contextlib.suppress(Exception):
                pool.shutdown(wait=False, cancel_futures=True)
            self.start()
            assert self._pool is not None
            return self._track(self._pool.submit(fit_window, window, self.options))

    def shutdown(self) -> None:
        """Stop the worker; a fit under way is finished first, queued ones are cancelled."""
        pool, self._pool = self._pool, None
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)


class LearningRefused(ValueError):
    """A control that cannot apply (a rollback to a version not kept); the message says why."""


@dataclass(frozen=True)
class Note:
    """What happened, as the session logs it (an event) and records it (``/gp_models``).

    ``kind``: the event's (``system`` for learning, ``setting`` for a clinician's control); ``before`` and
    ``after``: the event's (versions, or ``learning`` / ``frozen``).
    """

    text: str  #: the event's ("": recorded only, not an event)
    record: schema.GPModelRecord
    kind: schema.EventKind = "system"
    before: float | str | None = None
    after: float | str | None = None


@dataclass(frozen=True)
class _Fit:
    """A fit under way."""

    window: TrainingWindow
    submitted: float  # time.monotonic()
    future: Future[Fitted]


class GPLearning:
    """One session's GP-EKF learning (module docstring).

    Args:
        estimator: the stack's GP-EKF.
        trainer: the worker fits go to.
        stack: the stack (a failed GP-EKF learns no more).
    """

    def __init__(self, estimator: GPEKFEstimator, trainer: GPTrainer, stack: EstimatorStack):
        self.estimator = estimator
        self.trainer = trainer
        self._failed = stack.failed
        self._fit: _Fit | None = None
        self._accepted: dict[int, GPModelSet] = {}  # accepted, not installed yet: for their install's event
        self._rollback_by: str | None = None  # who asked for the waiting rollback
        self._models = estimator.filter.models
        self.last = ""
        self._queued_since: float | None = None  # time.monotonic() a ready window began to wait for the worker
        trainer.start()

    @classmethod
    def of(cls, stack: EstimatorStack, trainer: GPTrainer) -> GPLearning | None:
        """The learning of a stack's GP-EKF (None: the stack runs none)."""
        est = gp_ekf_of(stack)
        return None if est is None else cls(est, trainer, stack)

    @property
    def version(self) -> int:
        return self.estimator.model_version

    @property
    def fitting(self) -> Future[Fitted] | None:
        """The fit under way (None: none), for a caller that must wait for it (tests, benchmarks)."""
        return None if self._fit is None else self._fit.future

    # --- per sample ---------------------------------------------------------------------------------
    def poll(self, t: float) -> tuple[Note, ...]:
        """After the stack's step at session time ``t``: an install it made, a fit that is back, a window to
        fit. A few attribute reads when nothing happened."""
        f = self.estimator.filter
        notes: tuple[Note, ...] = ()
        if f.models is not self._models:
            notes = (self._installed(),)
        fit = self._fit
        if fit is not None:
            if fit.future.done():
                notes = (*notes, self._offer(t, fit))
        elif GP_EKF not in self._failed and f.window_ready:
            if f.frozen or self.trainer.may_submit(self):
                window = f.take_window()  # frozen: dropped
                self._queued_since = None
                if window is not None:
                    self._fit = _Fit(window, time.monotonic(), self.trainer.submit(window))
            elif self._queued_since is None:
                self._queued_since = time.monotonic()
        return notes

    def _installed(self) -> Note:
        f = self.estimator.filter
        before, self._models = self._models, f.models
        entry = f.installed[-1]
        trained = self._accepted.pop(entry.version, None)
        if self._rollback_by is not None:
            text = f"GP model v{entry.version} reinstalled at {entry.t:.2f} s (rollback by {self._rollback_by})"
            self._accepted.clear()  # the rollback replaced any accepted version still waiting
            self._rollback_by = None
        elif trained is not None:
            text = f"{window_text(entry.version, trained.steps, trained.span)}, {_rmse_text(trained.rmse)}: "
            text += f"installed at {entry.t:.2f} s"
        else:
            text = f"GP model v{entry.version} installed at {entry.t:.2f} s"
        self.last = text
        record = schema.GPModelRecord(t=entry.t, what="installed", version=entry.version, step=entry.step)
        return Note(text, record, before=before.version, after=entry.version)

    def _offer(self, t: float, fit: _Fit) -> Note:
        self._fit = None
        w = fit.window
        kept = self.version
        try:
            models, fit_s, _ = fit.future.result()
        except Exception as e:  # a crash in a fit is an event, never the session's end
            if isinstance(e, BrokenProcessPool):  # the next submit() replaces the pool
                why = "its worker process stopped unexpectedly"
            else:
                log.warning("GP fit of window %d failed", w.index, exc_info=True)
                why = f"{type(e).__name__}: {e}"
            text = f"GP model v{w.index} training on steps {w.steps[0]}-{w.steps[1]} ({w.span[0]:.1f}-"
            text += f"{w.span[1]:.1f} s) failed ({why}); kept v{kept}"
            self.last = text
            record = schema.GPModelRecord(t=t, what="failed", version=w.index, steps=w.steps, span_s=w.span, reason=why)
            return Note(text, record, before=kept, after=kept)
        offer = self.estimator.offer(models)
        record = schema.GPModelRecord(
            t=t, what="trained" if offer.accepted else "refused", version=models.version, steps=models.steps,
            span_s=models.span, rmse=rmse_of(models.rmse), fit_s=round(fit_s, 4), reason=offer.reason,
            arrays=arrays_of(models),
        )  # fmt: skip
        if offer.accepted:  # recorded now; its event is its install's, at the next heel strike
            self._accepted[models.version] = models
            self._rollback_by = None  # the accepted set replaced a waiting rollback
            return Note("", record)
        why = "learning is frozen" if self.estimator.frozen else f"the new model was refused: {offer.reason}"
        head = f"{window_text(models.version, models.steps, models.span)}, {_rmse_text(models.rmse)}"
        text = f"{head}: kept v{kept} ({why})"
        self.last = text
        return Note(text, record, before=kept, after=kept)

    # --- the clinician's controls -------------------------------------------------------------------
    def plan(self, control: schema.GPLearningControl, t: float) -> Note | None:
        """What ``control`` does, as its event and record (None: nothing, e.g. freezing a frozen learning);
        nothing changes until :meth:`apply`.

        Raises:
            LearningRefused: a rollback to a version that is not kept.
        """
        f = self.estimator.filter
        who = f" by {control.actor}"
        note = f" ({control.reason})" if control.reason else ""
        waiting = f.waiting_version
        if control.action in ("freeze", "unfreeze"):
            freeze = control.action == "freeze"
            if freeze == self.estimator.frozen:
                return None
            if freeze:
                text = f"GP learning frozen{who}: no retraining or installs until unfrozen, v{self.version} stays"
                if waiting is not None and self._rollback_by is None:
                    text += f" (v{waiting}, accepted, installs once unfrozen)"
            else:
                text = f"GP learning unfrozen{who}: retraining resumes"
                if waiting is not None and self._rollback_by is None:
                    text += f"; v{waiting}, accepted before, installs at the next heel strike"
            record = schema.GPModelRecord(
                t=t, what="frozen" if freeze else "unfrozen", version=self.version, actor=control.actor,
                reason=control.reason,
            )  # fmt: skip
            before, after = ("learning", "frozen") if freeze else ("frozen", "learning")
            return Note(text + note, record, "setting", before, after)
        version = control.version
        assert version is not None  # the schema's check
        if version not in f.kept_versions:
            kept = ", ".join(f"v{v}" for v in f.kept_versions)
            raise LearningRefused(f"GP model v{version} is not kept; a rollback can reinstall {kept}")
        text = f"GP model rollback to v{version}{who}: installed at the next heel strike"
        if waiting is not None and self._rollback_by is None:
            text += f" (v{waiting}, accepted and waiting, is dropped)"
        record = schema.GPModelRecord(t=t, what="rollback", version=version, actor=control.actor, reason=control.reason)
        return Note(text + note, record, "setting", float(self.version), float(version))

    def apply(self, control: schema.GPLearningControl) -> None:
        """Do what :meth:`plan` said (between two samples)."""
        if control.action == "rollback":
            assert control.version is not None
            why = self.estimator.rollback(control.version)
            if why:  # plan() checked it: cannot happen between the two
                raise LearningRefused(why)
            self._rollback_by = control.actor
        else:
            self.estimator.frozen = control.action == "freeze"

    def close(self) -> None:
        """The session stops: a fit under way is dropped (the shared worker finishes it, unheard)."""
        if self._fit is not None and self._fit.future is not None:
            self._fit.future.cancel()
        self._fit = None

    # --- what the dashboard shows ---------------------------------------------------------------------
    def kept_records(self, t: float) -> list[schema.GPModelRecord]:
        """At a recording's start: every kept version but the initial one, and one accepted but not yet
        installed, with its arrays (a re-run of the recording installs from them); the one in force is
        marked ``current``."""
        f = self.estimator.filter
        sets = {e.version: e.models for e in f.installed if e.version != f.initial.version} | self._accepted
        return [
            schema.GPModelRecord(
                t=t,
                what="kept",
                version=v,
                steps=m.steps,
                span_s=m.span,
                rmse=rmse_of(m.rmse),
                current=v == self.version,
                arrays=arrays_of(m),
            )
            for v, m in sorted(sets.items())
        ]

    def state(self, session_id: int, version: int | None = None) -> schema.GPLearningState:
        """The learning as the dashboard shows it, with the band of ``version`` too when given.

        Raises:
            LearningRefused: ``version`` is not kept.
        """
        f = self.estimator.filter
        sets = {f.initial.version: f.initial} | {e.version: e.models for e in f.installed}
        if version is not None and version not in sets:
            kept = ", ".join(f"v{v}" for v in sorted(sets))
            raise LearningRefused(f"GP model v{version} is not kept (kept: {kept})")
        installs: dict[int, list[float]] = {}
        for e in f.installed:
            if math.isfinite(e.t):
                installs.setdefault(e.version, []).append(e.t)
        fit = self._fit
        pending = None
        if fit is not None:
            w = fit.window
            running = round(time.monotonic() - fit.submitted, 3)
            pending = schema.GPPendingFit(version=w.index, steps=w.steps, span_s=w.span, running_s=running)
        return schema.GPLearningState(
            session_id=session_id,
            version=self.version,
            waiting=f.waiting_version,
            rollback=f.waiting_version is not None and self._rollback_by is not None,
            frozen=self.estimator.frozen,
            pending=pending,
            queued_s=None if self._queued_since is None else round(time.monotonic() - self._queued_since, 3),
            versions=[_info(v, m, v == f.initial.version, installs.get(v, [])) for v, m in sorted(sets.items())],
            last=self.last,
            phase=_BAND_PHASE.tolist(),
            current=_band(f.models),
            requested=None if version is None else _band(sets[version]),
        )


def _rmse_text(rmse: np.ndarray) -> str:
    """``held-out RMSE hip 1.1, knee 2.0, ankle 0.9 deg`` (the angles)."""
    angles = rmse[:3].tolist()
    shown = [f"{j} {v:.1f}" if math.isfinite(v) else f"{j} n/a" for j, v in zip(schema.GP_JOINTS, angles, strict=True)]
    return f"held-out RMSE {', '.join(shown)} deg"


def _info(version: int, m: GPModelSet, population: bool, installed: list[float]) -> schema.GPModelInfo:
    rmse = list(rmse_of(m.rmse).values())
    return schema.GPModelInfo(
        version=version,
        population=population,
        steps=None if population else m.steps,
        span_s=None if population else m.span,
        rmse_deg=dict(zip(schema.GP_JOINTS, rmse[:3], strict=True)),
        rmse_dps=dict(zip(schema.GP_JOINTS, rmse[3:], strict=True)),
        installed_t=installed,
    )


def _band(m: GPModelSet) -> schema.GPBand:
    """The angle GPs' means and +-2 sd (with noise) over :data:`_BAND_PHASE`."""
    mean, lower, upper = {}, {}, {}
    for joint, gp in zip(schema.GP_JOINTS, m.angle, strict=True):
        mu = gp.mean(_BAND_PHASE)
        sd = np.sqrt(gp.variance_at(_BAND_PHASE))
        mean[joint], lower[joint], upper[joint] = mu.tolist(), (mu - 2 * sd).tolist(), (mu + 2 * sd).tolist()
    return schema.GPBand(version=m.version, mean_deg=mean, lower_deg=lower, upper_deg=upper)
