"""Assistance follows intent (``intent_gain_boost``, :mod:`gaitscope.sessions.intent_boost`): whatever the intent
estimator says, the torque on the wire is finite and within ``[0, max_torque_Nm]`` and never steps; with
the setting on, the torque rises when the walker speeds up; off, nothing changes.

Driven through the real :class:`~gaitscope.sessions.live.runtime.SessionRuntime` (the torque the device is sent), with
an intent estimator double that says anything (NaN, infinities, huge values, any code) or the real one on a
simulated walk whose speed changes.
"""

from __future__ import annotations

import math
import time
from typing import Any, ClassVar

import numpy as np
import pytest
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray
from pydantic import ValidationError

from gaitscope.sessions import registry, schema
from gaitscope.sessions.intent_boost import MAX_STEP_S, IntentBoost
from gaitscope.sessions.live.runtime import SessionRuntime, SettingRejected
from gaitscope.sessions.live.sources import LiveDevice, frames_from_table
from gaitscope.sessions.synth.trials import sensor_trial
from tests.estimator_doubles import register

ANY_FLOAT = st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True)
OUTPUT = st.one_of(ANY_FLOAT, st.sampled_from([-1.0, 0.0, 1.0, 1e300, -1e300]), st.floats(-10.0, 10.0))
LIMITS = schema.SETTING_LIMITS
GAIN_RATE = LIMITS["torque_gain"][2]


class SaysAnything:
    """The ``intent`` estimator's interface, its outputs scripted row by row (then the last row again)."""

    name = "intent"
    inputs: tuple[str, ...] = ()
    optional_inputs: tuple[str, ...] = ()
    outputs = (
        ("desired_speed_m_s", "m/s"),
        ("intent_m_s", "m/s"),
        ("intent_code", "code"),
        ("intent_confidence", "1"),
        ("speed_m_s", "m/s"),
    )
    tunables: tuple[str, ...] = ()
    state = None
    covariance = None
    rows: ClassVar[list[list[float]]] = [[0.0] * 5]  # set by each example

    def __init__(self) -> None:
        self.k = 0

    def reset(self) -> None:
        self.k = 0

    def retune(self, **params: float) -> None:
        pass

    def step(self, t: float, z: NDArray[np.float64]) -> NDArray[np.float64]:
        row = self.rows[min(self.k, len(self.rows) - 1)]
        self.k += 1
        return np.array(row, dtype=np.float64)


def _runtime(client: TestClient, **session_settings: Any) -> SessionRuntime:
    ctx = client.app.state.ctx  # type: ignore[attr-defined]
    r = client.post(
        "/api/subjects", json={"code": f"B{time.monotonic_ns() % 10**9}", "leg_length_m": 0.9, "mass_kg": 75}
    )
    assert r.status_code == 201, r.text
    body = {"subject_id": r.json()["id"], "source": {"kind": "device"}, "settings": session_settings, "start": False}
    r = client.post("/api/sessions", json=body)
    assert r.status_code == 201, r.text
    session = ctx.store.get_session(r.json()["id"])
    model, _ = ctx.models.get(session.settings.model)
    subject = ctx.store.get_subject(session.subject_id)
    return SessionRuntime(session, subject, model, LiveDevice(), ctx.store, ctx.settings.data_dir)


def _walking_frames(n: int) -> list[schema.SensorFrame]:
    sensors, _, _ = sensor_trial([(1.2, 0.0, 4)], rate_hz=100.0)
    return frames_from_table(sensors)[:n]


FRAMES = _walking_frames(300)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    rows=st.lists(st.lists(OUTPUT, min_size=5, max_size=5), min_size=1, max_size=30),
    boost=st.floats(*LIMITS["intent_gain_boost"][:2]),
    gain=st.floats(*LIMITS["torque_gain"][:2]),
    bound=st.floats(*LIMITS["max_torque_Nm"][:2]),
    start=st.integers(0, 250),
)
def test_whatever_the_intent_says_the_torque_on_the_wire_is_finite_and_bounded(
    client: TestClient,
    monkeypatch: pytest.MonkeyPatch,
    rows: list[list[float]],
    boost: float,
    gain: float,
    bound: float,
    start: int,
) -> None:
    """The intent double says ``rows`` from frame ``start`` on (steady before, so the boost may be ramped
    up when it starts); the command sent for every frame is finite and within the session's bound."""
    register(monkeypatch, registry.descriptors()["intent"].built_by(lambda ctx: SaysAnything()))
    SaysAnything.rows = [[1.2, 0.3, 1.0, 10.0, 1.2]] * start + rows
    runtime = _runtime(
        client,
        estimators=["phase_ekf", "intent"],
        intent_gain_boost=boost,
        torque_gain=gain,
        max_torque_Nm=bound,
    )
    for frame in FRAMES:
        state = runtime.process(frame, time.time_ns())
        assert math.isfinite(state.torque_Nm) and 0.0 <= state.torque_Nm <= bound
        assert f'"torque_Nm":{state.torque_Nm!r}' in runtime.last_command
        assert abs(runtime.estimator.intent_boost.value) <= boost + 1e-12


@settings(max_examples=200, deadline=None)
@given(
    steps=st.lists(
        st.tuples(st.floats(-1.0, 1.0), OUTPUT, OUTPUT, ANY_FLOAT, st.one_of(st.none(), st.just("failed"))),
        min_size=1,
        max_size=60,
    ),
    boost=st.floats(*LIMITS["intent_gain_boost"][:2]),
    gain=st.floats(*LIMITS["torque_gain"][:2]),
    bound=st.floats(*LIMITS["max_torque_Nm"][:2]),
)
def test_the_effective_boost_ramps_and_the_torque_stays_bounded(
    steps: list[tuple[float, float, float, float, str | None]], boost: float, gain: float, bound: float
) -> None:
    """Arbitrary times (backwards too), codes, confidences, stack torques and failures: the boost never
    leaves ``[-boost, boost]``, moves at most at the gain ramp's rate, and the torque stays within the bound."""
    b = IntentBoost(["phase_ekf", "intent"], [("phase",), tuple(n for n, _ in SaysAnything.outputs)])
    t = 0.0
    for dt, code, confidence, torque, failed in steps:
        before = b.value
        y = None if failed else np.array([1.0, 0.1, code, confidence, 1.0])
        b.update(t + dt, [np.zeros(1), y], boost, gain)
        step = abs(b.value - before)
        assert abs(b.value) <= boost + 1e-12
        assert step <= GAIN_RATE / max(gain, 1.0) * min(max(dt, 0.0), MAX_STEP_S) + 1e-12
        out = b.torque(torque, bound)
        assert math.isfinite(out) and 0.0 <= out <= bound
        t += dt


def test_no_intent_estimator_or_a_silent_one_means_no_boost() -> None:
    alone = IntentBoost(["phase_ekf", "tbe"], [("phase",), ("phase",)])
    for k in range(100):
        assert alone.update(0.01 * k, [np.zeros(1), np.zeros(1)], 0.3, 1.0) == 0.0
    b = IntentBoost(["intent"], [tuple(n for n, _ in SaysAnything.outputs)])
    for k, y in enumerate([np.array([1.0, 0.1, math.nan, 5.0, 1.0]), None, np.array([1.0, 0.0, 1.0, 0.0, 1.0])]):
        assert b.update(0.01 * k, [y], 0.3, 1.0) == 0.0  # NaN code, failed, or "not sure" (confidence 0)


def _boosted_and_plain(client: TestClient, boost: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, SessionRuntime]:
    """The real intent estimator on a walk from 1.0 to 1.3 m/s, through two runtimes, one with ``boost``
    and one without: session times, both torques, and the boosted runtime."""
    sensors, _, _ = sensor_trial([(1.0, 0.0, 10), (1.3, 0.0, 6)], rate_hz=100.0)
    stack = {"estimators": ["phase_ekf", "intent"], "torque_gain": 1.0, "max_torque_Nm": 80.0}
    boosted, plain = _runtime(client, intent_gain_boost=boost, **stack), _runtime(client, **stack)
    t, a, b = [], [], []
    for frame in frames_from_table(sensors):
        now = time.time_ns()
        sa, sb = boosted.process(frame, now), plain.process(frame, now)
        t.append(sa.t)
        a.append(sa.torque_Nm)
        b.append(sb.torque_Nm)
    return np.array(t), np.array(a), np.array(b), boosted


def test_with_the_setting_on_the_torque_rises_when_the_walker_speeds_up(client: TestClient) -> None:
    t, boosted, plain, runtime = _boosted_and_plain(client, 0.3)
    pushing = plain > 5.0
    ratio = np.where(pushing, boosted / np.where(pushing, plain, 1.0), 1.0)
    assert ratio.max() <= 1.3 + 1e-9 and ratio.min() >= 0.7 - 1e-9  # within the boost
    assert (boosted <= 80.0).all()
    after = (t > 11.7) & (t < 13.5)  # the speed changes at the 11th stride (11.7 s): within two steps of it
    assert ratio[after].max() > 1.15  # assistance followed the speed-up
    # smooth: the effective gain moved at most at the gain ramp's rate (0.5/s at gain 1)
    both = pushing[1:] & pushing[:-1]
    assert np.abs(np.diff(ratio)[both]).max() <= 0.5 * 0.01 + 1e-9
    assert runtime.settings.intent_gain_boost == 0.3


def test_with_the_setting_off_nothing_changes(client: TestClient) -> None:
    _, off, plain, runtime = _boosted_and_plain(client, 0.0)
    assert np.array_equal(off, plain) and runtime.estimator.intent_boost.value == 0.0


def test_the_setting_is_validated_and_rate_limited_like_every_other(client: TestClient) -> None:
    with pytest.raises(ValidationError):
        schema.SettingsChange(intent_gain_boost=0.5)
    runtime = _runtime(client)
    assert runtime.settings.intent_gain_boost == 0.0  # off by default
    with pytest.raises(SettingRejected, match=r"intent_gain_boost may change by at most 0\.1"):
        runtime.change_settings(schema.SettingsChange(intent_gain_boost=0.3))
    runtime.change_settings(schema.SettingsChange(intent_gain_boost=0.1, reason="try it", confirm=True))
    with pytest.raises(SettingRejected, match="intent_gain_boost changed"):
        runtime.change_settings(schema.SettingsChange(intent_gain_boost=0.2))
    ctx = client.app.state.ctx  # type: ignore[attr-defined]
    [event] = [e for e in ctx.store.list_events(runtime.session.id) if e.kind == "setting"]
    assert (event.field, event.before, event.after) == ("intent_gain_boost", 0.0, 0.1)


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    boost=st.floats(0.01, LIMITS["intent_gain_boost"][1]),
    gain=st.floats(0.2, LIMITS["torque_gain"][1]),
    bound=st.floats(*LIMITS["max_torque_Nm"][:2]),
    confidence=st.floats(0.5, 20.0),
)
def test_the_boost_stays_within_the_soft_starts_ramp(
    client: TestClient, monkeypatch: pytest.MonkeyPatch, boost: float, gain: float, bound: float, confidence: float
) -> None:
    """A walker speeding up from the first frame (issue #21: 1.26x the unboosted torque during the 3 s ramp):
    while the soft start ramps the gain, the boosted torque never exceeds the unboosted one (the ramp's), then
    comes in as a ramp of its own: the effective gain within ``0.5/s x t``, the torque within the ramped bound."""
    register(monkeypatch, registry.descriptors()["intent"].built_by(lambda ctx: SaysAnything()))
    SaysAnything.rows = [[1.2, 0.3, 1.0, confidence, 1.2]]
    stack: dict[str, Any] = {"estimators": ["phase_ekf", "intent"], "torque_gain": gain, "max_torque_Nm": bound}
    boosted, plain = _runtime(client, intent_gain_boost=boost, **stack), _runtime(client, **stack)
    _check_within_the_ramp(boosted, plain, gain, bound)


def _check_within_the_ramp(boosted: SessionRuntime, plain: SessionRuntime, gain: float, bound: float) -> int:
    """Both runtimes through :data:`FRAMES`, the soft start's limits checked on every sample; how many samples
    the boost raised the torque."""
    pushed = 0
    for frame in FRAMES:
        now = time.time_ns()
        a, b = boosted.process(frame, now), plain.process(frame, now)
        ramp_gain = GAIN_RATE * a.t
        assert a.torque_Nm <= min(bound, LIMITS["max_torque_Nm"][2] * a.t) + 1e-9
        if ramp_gain < gain:  # the soft start still ramps the gain: the ramped, unboosted torque is the most
            assert a.torque_Nm <= b.torque_Nm + 1e-9, (a.t, a.torque_Nm, b.torque_Nm)
        elif b.torque_Nm > 0.0:  # then the effective gain follows the ramp: gain x factor <= 0.5/s x t
            assert a.torque_Nm / b.torque_Nm * gain <= max(gain, ramp_gain) + 1e-9
        pushed += a.torque_Nm > b.torque_Nm + 1e-9
    return pushed


def test_once_the_ramp_allows_it_the_boost_comes_in(client: TestClient, monkeypatch: pytest.MonkeyPatch) -> None:
    register(monkeypatch, registry.descriptors()["intent"].built_by(lambda ctx: SaysAnything()))
    SaysAnything.rows = [[1.2, 0.3, 1.0, 10.0, 1.2]]
    stack: dict[str, Any] = {"estimators": ["phase_ekf", "intent"], "torque_gain": 0.5, "max_torque_Nm": 80.0}
    boosted, plain = _runtime(client, intent_gain_boost=0.3, **stack), _runtime(client, **stack)
    assert _check_within_the_ramp(boosted, plain, 0.5, 80.0) > 50  # the gain ramp ends at 1 s of 3
