"""Speed-change intent onsets: one per change of the intent class to speeding up or slowing down, none while
it holds, none for a return to steady."""

from __future__ import annotations

import numpy as np

from gaitscope.sessions.live.intent_events import IntentOnset, IntentOnsets

NAMES = ("phase_ekf", "intent")
OUTPUTS = (
    ("phase", "phase_rate"),
    ("desired_speed_m_s", "intent_m_s", "intent_code", "intent_confidence", "speed_m_s"),
)


def _sample(code: float, desired: float = 1.2, change: float = 0.0, confidence: float = 0.0) -> list[np.ndarray]:
    return [np.array([0.5, 1.0]), np.array([desired, change, code, confidence, 1.1])]


def test_one_onset_per_change_to_speeding_up_or_slowing_down() -> None:
    watch = IntentOnsets(NAMES, OUTPUTS)
    assert watch.active
    held = [
        _sample(0.0),
        _sample(1.0, 1.32, 0.12, 2.44),  # 0 -> +1: an onset
        _sample(1.0, 1.32, 0.12, 2.44),
        _sample(1.0, 1.40, 0.08, 1.5),  # still speeding up at the next mid-stance: no new event
        _sample(0.0, 1.40, 0.0, 0.2),  # back to steady: no event
        _sample(-1.0, 1.25, -0.15, 3.0),  # 0 -> -1
        _sample(1.0, 1.30, 0.05, 1.2),  # -1 -> +1: the opposite sign
    ]
    onsets = [watch.update(s) for s in held]
    assert [None if o is None else o.code for o in onsets] == [None, 1, None, None, None, -1, 1]
    first = onsets[1]
    assert first == IntentOnset(1, 1.32, 0.12, 2.44)
    assert first.text == "speeding up: desired 1.32 m/s (+0.12 m/s, 2.4 SD)"
    assert first.desired_before_m_s == 1.32 - 0.12
    assert onsets[5] is not None and onsets[5].text == "slowing down: desired 1.25 m/s (-0.15 m/s, 3.0 SD)"


def test_a_failed_estimator_reports_nothing_and_a_restart_reports_again() -> None:
    watch = IntentOnsets(NAMES, OUTPUTS)
    assert watch.update(_sample(1.0, 1.3, 0.1, 2.0)) is not None
    assert watch.update([np.array([0.5, 1.0]), None]) is None  # failed: outputs None
    assert watch.update(_sample(1.0, 1.3, 0.1, 2.0)) is None  # the same class as before the gap
    assert watch.update(_sample(0.0, 0.0, 0.0, 0.0)) is None  # restarted after a pause: steady
    assert watch.update(_sample(1.0, 1.3, 0.1, 2.0)) is not None


def test_a_stack_without_the_intent_estimator_watches_nothing() -> None:
    watch = IntentOnsets(NAMES[:1], OUTPUTS[:1])
    assert not watch.active
    assert watch.update([np.array([0.5, 1.0])]) is None
