"""``gaitscope bench``'s rows: one per registered estimator (with its baseline where it has one), the whole
stack, and what ``run_bench`` prints and returns. Behaviour only, on few samples: how fast is the
bench's business, not the tests'."""

from __future__ import annotations

import math

import pytest

from gaitscope.sessions.offline import bench
from gaitscope.sessions.offline.baselines import BASELINES
from gaitscope.sessions.registry import ESTIMATORS, OPT_IN

SAMPLES, REFERENCE = 150, 40


@pytest.fixture(scope="module")
def rows() -> dict[str, dict[str, float]]:
    return bench.estimator_costs(SAMPLES, REFERENCE)


def _positive(v: float) -> bool:
    return math.isfinite(v) and v > 0


def test_every_registered_estimator_has_a_row_with_positive_finite_costs(rows) -> None:
    assert list(rows) == list(ESTIMATORS)  # the opt-in ones too, in the registry's order
    for name, row in rows.items():
        assert row["samples"] == SAMPLES, name
        assert _positive(row["median_us"]) and _positive(row["p95_us"]), name
        assert row["p95_us"] >= row["median_us"], name


def test_baselines_are_timed_where_there_is_one_and_nowhere_else(rows) -> None:
    for name, row in rows.items():
        if name not in BASELINES:
            assert not any(k.startswith("ref_") or k == "ratio" for k in row), name
            continue
        assert row["ref_samples"] == REFERENCE, name
        assert _positive(row["ref_median_us"]) and _positive(row["ref_p95_us"]), name
        assert row["ratio"] == pytest.approx(row["ref_median_us"] / row["median_us"])
    assert "ratio" not in rows["tbe"] and "ratio" not in rows["hs_detector"]


def test_the_backup_agrees_with_its_filterpy_twin(rows) -> None:
    row = rows["hs_backup"]
    assert row["max_output_diff"] < 1e-9
    assert row["max_state_diff"] < 1e-9 and row["max_cov_diff"] < 1e-9
    assert "max_state_diff" not in rows["phase_ekf"]  # filter core only: nothing to compare output for output


def test_the_reference_samples_are_capped_by_the_samples() -> None:
    row = bench.estimator_costs(samples=30, reference_samples=1000)["hs_backup"]
    assert row["samples"] == row["ref_samples"] == 30


def test_no_reference_samples_leaves_the_baselines_out(capsys) -> None:
    rows = bench.estimator_costs(samples=30, reference_samples=0)
    assert all("ratio" not in row and _positive(row["median_us"]) for row in rows.values())
    bench._print_estimators(rows)
    assert capsys.readouterr().out.count("not run") == len(BASELINES)


def test_run_bench_prints_a_line_per_estimator_and_returns_every_row(capsys) -> None:
    out = bench.run_bench(crossval=False, reference_samples=REFERENCE, samples=SAMPLES, replay_minutes=0.05)
    text = capsys.readouterr().out
    lines = text.splitlines()
    for name in ESTIMATORS:
        label = f"{name} (opt-in)" if name in OPT_IN else name
        (line,) = [x for x in lines if x.startswith(f"  {label} ")]
        if name in BASELINES:
            assert BASELINES[name].label in line and line.rstrip().endswith("x")
        else:
            assert line.rstrip().endswith("no reference")
        for key in ("samples", "median_us", "p95_us"):
            assert _positive(out[f"estimator_{name}_{key}"])
    assert _positive(out["stack_stack_median_us"]) and out["stack_samples"] == SAMPLES
    assert "EstimatorStack.step" in text and "max |output diff|" in text
    assert "crossval_wall_s" not in out
    # a GP-EKF retraining, against the walking time it has and against GPy's documented sparse GP
    assert 0 < out["gp_retrain_fit_median_s"] < out["gp_retrain_budget_s"] and out["gp_retrain_steps"] == 5
    assert _positive(out["gp_retrain_ref_median_s"]) and "GP-EKF retraining" in text


def test_without_reference_samples_the_phase_ekf_row_says_its_reference_was_not_run(capsys) -> None:
    bench.run_bench(crossval=False, reference_samples=0, samples=SAMPLES, replay_minutes=0.05, gp_retrain=False)
    text = capsys.readouterr().out
    assert "filterpy reference   not run (--reference-samples 0)" in text
    assert "speed-up (median)" not in text and " 0.0x" not in text
