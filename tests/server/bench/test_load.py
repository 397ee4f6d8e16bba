"""The load benchmark's report: a load where a stream got no sample is reported as such, not a crash."""

from __future__ import annotations

import math

import pytest

from gaitscope.server.bench.load import Stream, _summary


def _result(streams: list[Stream]) -> dict[str, object]:
    return {"streams": streams, "generator_cpu_pct": 20.0, "gp_trained": []}


def test_streams_without_a_sample_are_counted_and_their_latency_is_unknown(capsys: pytest.CaptureFixture[str]) -> None:
    out = _summary("load: 2 devices x 1 clients", _result([Stream(), Stream()]), 1.0, 10.0, (300.0, 310.0))
    assert out["streams_without_samples"] == 2.0
    assert math.isnan(out["p95_ms"]) and math.isnan(out["p50_ms"]) and math.isnan(out["p99_ms"])
    assert out["rate_min_hz"] == 0.0
    assert "2 of 2 streams received no sample" in capsys.readouterr().out


def test_a_stream_without_samples_beside_others_does_not_hide_them(capsys: pytest.CaptureFixture[str]) -> None:
    fed = Stream(latencies_ms=[10.0, 20.0, 30.0], received=3, first=0.0, last=1.0)
    out = _summary("load: 2 devices x 1 clients", _result([fed, Stream()]), 1.0, 10.0, (300.0, 310.0))
    assert out["streams_without_samples"] == 1.0
    assert out["p50_ms"] == 20.0
    assert "1 of 2 streams received no sample" in capsys.readouterr().out


def test_no_streams_at_all() -> None:
    out = _summary("load", _result([]), 1.0, 10.0, (300.0, 310.0))
    assert out["streams"] == 0.0 and math.isnan(out["p95_ms"]) and out["rate_mean_hz"] == 0.0
