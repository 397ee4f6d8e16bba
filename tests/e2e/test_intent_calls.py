"""Speed-change calls in the live view (issue #26, "intent that does not cry wolf"), real server and browser.

A simulated walker (cohort subject 0, its sensors at 100 Hz in real time) walks a minute steady at 1.0 m/s,
then the belt goes to 1.4 m/s. The stack's intent estimator calls speed-change episodes
(:mod:`gaitscope.estimators.intent_episodes`): over the steady minute it raises at most one intent event,
and the change raises one "speeding up" event within a few steps, which the live view's event list shows.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from gaitscope.sessions.synth.trials import sensor_trial
from tests.e2e.accounts import call
from tests.e2e.pages import Watched

playwright_api = pytest.importorskip("playwright.sync_api")
expect = playwright_api.expect

SCHEDULE = [(1.0, 0.0, 55), (1.4, 0.0, 12)]
RATE_HZ, SEED = 100.0, 7


def _change_time() -> float:
    """Session time (s) of the first sample at the new belt speed, from the same simulation the server runs."""
    sensors, _, _ = sensor_trial(SCHEDULE, subject=0, rate_hz=RATE_HZ, seed=SEED)
    fast = sensors["gt_speed_m_s"].to_numpy(np.float64) > 1.2
    return float(sensors["time_s"].to_numpy(np.float64)[np.argmax(fast)])


def test_a_steady_minute_is_quiet_and_speeding_up_is_called_within_a_few_steps(server: str, watched: Watched) -> None:
    page = watched.page
    subject = call(server, "POST", "/api/subjects", {"code": "WOLF1", "leg_length_m": 0.9, "mass_kg": 70.0})
    protocol = [{"speed_m_s": v, "incline_deg": r, "strides": n} for v, r, n in SCHEDULE]
    source = {"kind": "simulated", "rate_hz": RATE_HZ, "protocol": protocol, "seed": SEED, "loop": False}
    session = call(server, "POST", "/api/sessions", {"subject_id": subject["id"], "source": source})
    change = _change_time()
    assert 55.0 < change < 75.0  # a minute or so of steady walking first

    page.goto(f"{server}/#/sessions/{session['id']}", wait_until="domcontentloaded")
    expect(page.get_by_test_id("live-indicator")).to_have_text("LIVE", timeout=20_000)
    speeding = page.get_by_test_id("event-row").and_(page.locator("[data-kind=intent]")).filter(has_text="speeding up")
    expect(speeding.last).to_be_visible(timeout=int((change + 30.0) * 1000))

    events: list[dict[str, Any]] = [
        e for e in call(server, "GET", f"/api/sessions/{session['id']}/events") if e["kind"] == "intent"
    ]
    steady = [e for e in events if e["t"] < change]
    after = [e for e in events if e["t"] >= change]
    assert len(steady) <= 1, steady
    assert after, events
    first = after[0]
    assert first["text"].startswith("speeding up"), first
    assert first["t"] - change < 3.0, (first, change)  # a few steps (a step takes about 0.55 s)
    assert first["after"] > first["before"]  # the desired speed rose
