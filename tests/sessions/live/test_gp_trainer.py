"""The GP-EKF's shared fitting worker (:class:`gaitscope.sessions.live.gp_learning.GPTrainer`): one fit at a time,
within its duty budget, the session that has asked longest first. On a fake clock and a fit that returns
when told, in a worker thread, so that every step is deterministic."""

from __future__ import annotations

import threading
import time
from types import SimpleNamespace
from typing import Any

import pytest

from gaitscope.sessions.live import gp_learning as gl


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> list[float]:
    now = [100.0]
    monkeypatch.setattr(gl, "time", SimpleNamespace(monotonic=lambda: now[0], perf_counter=time.perf_counter))
    return now


def _fits(monkeypatch: pytest.MonkeyPatch, fit_s: float, wall_s: float | None = None) -> threading.Event:
    """Fits that finish when the event is set, each reporting ``fit_s`` seconds of CPU (and ``wall_s`` of wall
    time: ``fit_s`` when not given)."""
    go = threading.Event()

    def fit(window: Any, options: Any) -> tuple[Any, float, float]:
        go.wait(10)
        return window, fit_s if wall_s is None else wall_s, fit_s

    monkeypatch.setattr(gl, "fit_window", fit)
    return go


def test_one_fit_at_a_time_then_a_pause_that_keeps_the_worker_within_its_duty(
    monkeypatch: pytest.MonkeyPatch, clock: list[float]
) -> None:
    go = _fits(monkeypatch, fit_s=2.0)
    trainer = gl.GPTrainer("thread", duty=0.25)  # a 2 s fit, then 6 s without one
    a, b = object(), object()
    try:
        assert trainer.may_submit(a)
        fit = trainer.submit("window a")  # type: ignore[arg-type]
        assert not trainer.may_submit(b)  # a fit is under way
        go.set()
        assert fit.result(10) == ("window a", 2.0, 2.0)
        clock[0] += 5.9
        assert not trainer.may_submit(b)  # within the pause
        clock[0] += 0.2
        assert trainer.may_submit(b)
    finally:
        trainer.shutdown()


def test_the_pause_counts_the_cpu_a_fit_used_not_the_time_it_waited_for_a_core(
    monkeypatch: pytest.MonkeyPatch, clock: list[float]
) -> None:
    go = _fits(monkeypatch, fit_s=0.5, wall_s=40.0)  # a niced worker on a busy machine: 0.5 s of CPU in 40 s
    trainer = gl.GPTrainer("thread", duty=0.25)
    a = object()
    try:
        assert trainer.may_submit(a)
        fit = trainer.submit("window a")  # type: ignore[arg-type]
        go.set()
        _finished(fit)
        clock[0] += 1.4
        assert not trainer.may_submit(a)  # 3 x 0.5 s of CPU
        clock[0] += 0.2
        assert trainer.may_submit(a)  # not 3 x 40 s
    finally:
        trainer.shutdown()


def _a_window() -> Any:
    """Five stances of 0.6 s at 100 Hz, smooth joint angles of the phase."""
    import numpy as np

    from gaitscope.estimators.gp_models import TrainingWindow

    n = 60
    phase = np.tile(np.arange(n) / n, 5)
    angle = np.stack([20 * np.cos(np.pi * phase), 10 * np.sin(np.pi * phase), 5 * np.sin(2 * np.pi * phase)], axis=1)
    return TrainingWindow(
        index=1, t=np.arange(5 * n) / 100.0, step=np.repeat(np.arange(1, 6), n).astype(np.int64), phase=phase,
        phase_rate=np.full(5 * n, 1 / 0.6), angle=angle, velocity=np.gradient(angle, 0.01, axis=0),
    )  # fmt: skip


def test_a_real_fit_reports_its_wall_and_cpu_time() -> None:
    window = _a_window()
    models, wall_s, cpu_s = gl.fit_window(window, gl.FIT_OPTIONS)
    assert models.version == window.index
    assert 0.0 < cpu_s and 0.0 < wall_s


def _finished(fit: Any) -> None:
    """Wait until ``fit`` is done and the trainer's own done-callback (registered when it was submitted, so run
    before this one, in the thread that finished it) has counted it: no sleep, no race."""
    seen = threading.Event()
    fit.add_done_callback(lambda _: seen.set())
    assert seen.wait(10), "the fit never finished"


def test_the_session_that_asked_first_goes_first_and_one_that_stopped_asking_loses_its_place(
    monkeypatch: pytest.MonkeyPatch, clock: list[float]
) -> None:
    go = _fits(monkeypatch, fit_s=0.0)
    trainer = gl.GPTrainer("thread", duty=1.0)
    a, b, c = object(), object(), object()
    try:
        assert trainer.may_submit(a)
        fit = trainer.submit("window a")  # type: ignore[arg-type]
        assert not trainer.may_submit(c)  # c asks first, while a's fit runs
        clock[0] += 0.1
        assert not trainer.may_submit(b)
        go.set()
        _finished(fit)
        assert not trainer.may_submit(b)  # c asked before b
        assert trainer.may_submit(c)
        fit = trainer.submit("window c")  # type: ignore[arg-type]
        _finished(fit)
        assert trainer.may_submit(b)  # then b
        go.clear()
        fit = trainer.submit("window b")  # type: ignore[arg-type]
        assert not trainer.may_submit(a)  # a asks during b's fit, then goes quiet (stopped, or frozen)
        clock[0] += 0.5
        assert not trainer.may_submit(c)
        go.set()
        _finished(fit)
        assert not trainer.may_submit(c)  # a asked 0.5 s ago: its turn
        clock[0] += 0.6
        assert trainer.may_submit(c)  # a has not asked for 1.1 s: c's turn
    finally:
        go.set()
        trainer.shutdown()


def test_a_duty_outside_0_1_is_refused() -> None:
    for duty in (0.0, -1.0, 1.5, float("nan")):
        with pytest.raises(ValueError, match="duty must be in"):
            gl.GPTrainer("thread", duty=duty)
