"""The intent estimator's bench row: both split by events, costs positive, the baseline agreeing."""

from __future__ import annotations

import math

from gaitscope.sessions.offline.intent_bench import intent_cost


def test_the_row_times_both_between_and_at_events_and_the_baseline_agrees() -> None:
    row = intent_cost(strides=3)
    assert row["events"] >= 8 and row["samples"] > row["events"]
    for prefix in ("", "ref_"):
        for part in ("between", "events"):
            med, p95 = row[f"{prefix}{part}_median_us"], row[f"{prefix}{part}_p95_us"]
            assert math.isfinite(med) and 0 < med <= p95
    assert row["between_ratio"] > 0 and row["events_ratio"] > 0
    assert row["max_output_diff"] < 1e-9
