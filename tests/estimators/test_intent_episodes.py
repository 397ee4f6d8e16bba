"""Speed-change episodes: one call per change, held while it lasts, none on steady walking."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gaitscope.estimators.intent_episodes import DEFAULT_RULE, EpisodeRule, SpeedEpisodes

RULE = EpisodeRule(threshold_m_s=0.1, speed_threshold_m_s=0.08, window_steps=6, min_steps=3, settle_m_s=0.03)


def _run(rule: EpisodeRule, desired: list[float], speed: list[float] | None = None) -> list[int]:
    e = SpeedEpisodes(rule)
    return [e.step(d, v) for d, v in zip(desired, speed if speed is not None else desired, strict=True)]


def test_steady_walking_with_noise_below_the_thresholds_calls_nothing() -> None:
    rng = np.random.default_rng(1)
    desired = list(1.2 + 0.02 * rng.standard_normal(500))
    speed = list(1.2 + 0.01 * rng.standard_normal(500))
    assert _run(RULE, desired, speed) == [0] * 500


def test_a_speed_up_is_one_episode_held_until_the_walker_is_steady_again() -> None:
    desired = [1.0] * 6 + [1.15, 1.25, 1.3, 1.31, 1.3, 1.3, 1.3, 1.3]
    speed = [1.0] * 6 + [1.05, 1.15, 1.25, 1.29, 1.3, 1.3, 1.3, 1.3]
    codes = _run(RULE, desired, speed)
    # opens at the first step 0.15 m/s above the reference, holds through the change, closes after two
    # steps that changed less than 0.03 m/s
    assert codes == [0] * 6 + [1, 1, 1, 1, 0, 0, 0, 0]
    onsets = sum(1 for a, b in zip([0, *codes], codes, strict=False) if b and b != a)
    assert onsets == 1


def test_after_an_episode_the_reference_starts_over_at_the_new_speed() -> None:
    desired = [1.0] * 4 + [1.2] * 12
    codes = _run(RULE, desired)
    assert codes[4:7] == [1, 1, 0]  # the step, then two steady steps close it
    assert codes[6:] == [0] * 10  # steady at 1.2: no second call


def test_the_measured_speed_alone_opens_a_slow_down_the_desired_speed_missed() -> None:
    desired = [1.2] * 5 + [1.15, 1.12, 1.12]
    speed = [1.2] * 5 + [1.1, 1.05, 1.05]
    codes = _run(RULE, desired, speed)
    assert codes[5] == -1  # 0.1 m/s slower than the reference: past the speed's 0.08
    no_speed = EpisodeRule(threshold_m_s=0.1, speed_threshold_m_s=math.inf, window_steps=6, min_steps=3)
    assert _run(no_speed, desired, speed) == [0] * 8


def test_no_call_before_the_reference_has_its_steps() -> None:
    assert _run(RULE, [1.0, 1.0, 1.5]) == [0, 0, 0]  # two steps only: 1.5 joins the reference
    assert _run(RULE, [1.0, 1.0, 1.0, 1.5]) == [0, 0, 0, 1]


def test_an_episode_ends_after_its_longest_length() -> None:
    rule = EpisodeRule(threshold_m_s=0.1, window_steps=4, min_steps=3, settle_steps=2, max_steps=4)
    desired = [1.0, 1.0, 1.0] + [1.2 + 0.1 * k for k in range(8)]  # never steady
    codes = _run(rule, desired)
    assert codes[3:8] == [1, 1, 1, 1, 0]


def test_non_finite_input_starts_the_walk_over() -> None:
    e = SpeedEpisodes(RULE)
    for _ in range(4):
        e.step(1.0, 1.0)
    assert e.step(1.3, 1.3) == 1
    assert e.step(math.nan, 1.3) == 0 and e.code == 0
    assert [e.step(1.3, 1.3) for _ in range(3)] == [0, 0, 0]  # a new reference


@pytest.mark.parametrize(
    "kwargs",
    [
        {"threshold_m_s": 0.0},
        {"threshold_m_s": math.nan},
        {"speed_threshold_m_s": -1.0},
        {"min_steps": 0},
        {"min_steps": 9, "window_steps": 8},
        {"settle_steps": 3, "max_steps": 2},
        {"settle_m_s": -0.1},
    ],
)
def test_a_rule_that_makes_no_sense_is_refused(kwargs: dict[str, float]) -> None:
    with pytest.raises(ValueError):
        EpisodeRule(**kwargs)  # type: ignore[arg-type]


_SPEEDS = st.one_of(st.floats(-1e6, 1e6), st.sampled_from([math.nan, math.inf, -math.inf]))


@given(st.lists(st.tuples(_SPEEDS, _SPEEDS), max_size=60))
def test_any_input_gives_a_code_in_minus_one_to_one(steps: list[tuple[float, float]]) -> None:
    e = SpeedEpisodes(RULE)
    for d, v in steps:
        assert e.step(d, v) in (-1, 0, 1)
        assert math.isfinite(e.deviation)


def test_the_estimator_retunes_its_rule_and_refuses_what_makes_no_sense() -> None:
    from gaitscope.estimators.intent_estimator import IntentEstimator

    est = IntentEstimator(0.9)
    assert est.threshold_m_s == DEFAULT_RULE.threshold_m_s
    est.retune(threshold_m_s=0.2)
    assert est.threshold_m_s == 0.2 and est.speed_threshold_m_s == DEFAULT_RULE.speed_threshold_m_s
    for bad in (0.0, -0.1, math.nan):
        with pytest.raises(ValueError):
            est.retune(speed_threshold_m_s=bad)
    assert est.speed_threshold_m_s == DEFAULT_RULE.speed_threshold_m_s  # unchanged by a refusal
    with pytest.raises(ValueError, match="per step"):
        IntentEstimator(0.9, episodes=None).retune(threshold_m_s=0.2)
