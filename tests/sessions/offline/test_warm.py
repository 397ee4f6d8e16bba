"""``gaitscope warm`` (:mod:`gaitscope.sessions.offline.warm`): after it, a replay (both paths) and a review's
re-run compile nothing new. Each numba kernel's signatures are read before and after them; a kernel that
gains one was reached by a path (or with argument types) that ``warm`` misses, and would compile inside the
first replay after an install. The live sessions' side is ``tests/sessions/live/test_warmup.py``'s."""

from __future__ import annotations

from pathlib import Path

from gaitscope.estimators.pipeline import PipelineConfig
from gaitscope.sessions import schema
from gaitscope.sessions.estimation import estimate
from gaitscope.sessions.formats.models import default_model_path, load_model
from gaitscope.sessions.live.sources import frames_from_table
from gaitscope.sessions.offline.replay import replay_file
from gaitscope.sessions.offline.warm import compiled, warm
from gaitscope.sessions.synth.trials import replay_columns, sensor_trial


def test_after_warm_replays_and_reviews_compile_nothing_new(tmp_path: Path) -> None:
    said: list[str] = []
    took = warm(said.append)
    assert set(took) == {"sessions", "replay"} and len(said) == 2
    before = compiled()
    assert sum(len(sigs) for sigs in before.values()) >= 5  # the entry kernels, compiled or loaded

    model, _ = load_model(default_model_path())
    sensors, leg, mass = sensor_trial([(0.9, 5.0, 8), (1.4, -5.0, 8)], subject=3, rate_hz=200.0, seed=7)
    trial = tmp_path / "trial.csv"
    replay_columns(sensors).to_csv(trial, index=False, float_format="%.6f")
    for supervised in (True, False):
        replay_file(trial, tmp_path / f"out-{supervised}.csv", model, PipelineConfig(leg, mass), supervised=supervised)
    frames = frames_from_table(sensors)[:2000]
    assert estimate(frames, model, leg, mass, schema.SessionSettings(), time_origin=0.0)  # a review's re-run

    after = compiled()
    grown = {k: sorted(after[k] - before.get(k, frozenset())) for k in after if after[k] - before.get(k, frozenset())}
    assert not grown, f"compiled after warm: {grown}"
