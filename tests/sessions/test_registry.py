"""The registry's declarations (what a screen and a review's picker know without building anything) match
the estimators it builds, and :func:`~sessions.registry.feeds` says which ones a log's channels can run."""

from __future__ import annotations

import pytest

from estimators.pipeline import TrainedModel
from sessions.registry import DECLARED, ESTIMATORS, Feed, StackContext, feeds, resolve

HS = "heel_strike"


def test_each_registered_estimator_declares_what_it_is_built_as(small_model: TrainedModel) -> None:
    ctx = StackContext(small_model, 0.9, 70.0, 0.01)
    assert list(DECLARED) == list(ESTIMATORS)
    for name, make in ESTIMATORS.items():
        est = make(ctx)
        assert (est.name, est.inputs, est.outputs) == (name, DECLARED[name].inputs, DECLARED[name].outputs)
    assert {n: d.label for n, d in DECLARED.items()} == {
        "hs_detector": "Heel-strike detector",
        "phase_ekf": "Phase EKF (seed 000)",
        "tbe": "Timing-based estimate",
        "hs_backup": "Heel-strike backup",
    }


def test_feeds_counts_a_channel_an_earlier_estimator_derives() -> None:
    every = {"foot_angle_deg", "foot_vel_dps", "shank_angle_deg", "shank_vel_dps", HS}
    assert feeds(every) == {n: Feed((), {}) for n in ESTIMATORS}
    # the foot angle alone: its velocity is differentiated, heel strikes come from the detector or the EKF
    foot = feeds({"foot_angle_deg"})
    assert foot["hs_detector"] == foot["phase_ekf"] == Feed((), {})
    assert foot["tbe"] == foot["hs_backup"] == Feed((), {HS: ("hs_detector", "phase_ekf")})
    # heel strikes alone: only the estimators that read nothing else
    strikes = feeds({HS})
    assert strikes["hs_detector"] == Feed(("foot_angle_deg", "foot_vel_dps"), {})
    assert strikes["phase_ekf"] == Feed(("foot_angle_deg",), {})
    assert strikes["tbe"] == strikes["hs_backup"] == Feed((), {})
    assert all(f.missing for f in feeds(set()).values())


@pytest.mark.parametrize("channels", [{"foot_angle_deg"}, {HS}, {"foot_angle_deg", HS}, {"shank_angle_deg", HS}])
def test_feeds_agrees_with_what_resolve_builds(small_model: TrainedModel, channels: set[str]) -> None:
    ctx = StackContext(small_model, 0.9, 70.0, 0.01)
    runnable = [n for n, f in feeds(channels).items() if not f.missing]
    assert [e.name for e in resolve(runnable, channels, ctx)] == runnable
