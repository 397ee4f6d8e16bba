"""``gaitscope replay`` under arbitrary input: a bounded torque in every row, or exit 2 with a reason.

Reproduces: a replay CSV with values of 1e308 wrote NaN torque rows, and one with denormal or huge
times ended in a LinAlgError traceback.
"""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gaitscope.server.cli import main
from gaitscope.sessions import schema

MAX_TORQUE = 35.0
ANY = st.floats(allow_nan=False, allow_infinity=False, allow_subnormal=True)  # the CSV refuses NaN and inf cells


def _replay(tmp: Path, table: pd.DataFrame, capsys: pytest.CaptureFixture[str]) -> tuple[int, pd.DataFrame | None]:
    src, out = tmp / "in.csv", tmp / "out.csv"
    out.unlink(missing_ok=True)
    table.to_csv(src, index=False, float_format="%.17g")
    code = main(["replay", str(src), "--out", str(out), "--max-torque", str(MAX_TORQUE), "--torque-gain", "3"])
    err = capsys.readouterr().err
    if code != 0:
        assert (code == 2 and "time_s" in err) or "row" in err or "column" in err, err
        assert not out.exists()
        return code, None
    return code, pd.read_csv(out)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    steps=st.lists(st.one_of(st.floats(5e-324, 1e300), st.floats(0.005, 0.02)), min_size=2, max_size=30),
    values=st.lists(st.lists(st.one_of(ANY, st.floats(-100, 100)), min_size=6, max_size=6), min_size=30, max_size=30),
    start=st.one_of(st.just(0.0), ANY),
)
def test_any_numbers_give_bounded_torques_or_a_clear_refusal(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], steps: list[float], values: list[list[float]], start: float
) -> None:
    times, t = [], start
    for dt in steps:
        times.append(t)
        t = t + dt
    table = pd.DataFrame(values[: len(times)], columns=list(schema.REPLAY_SIGNALS))
    table.insert(0, "time_s", times)
    _code, out = _replay(tmp_path, table, capsys)
    if out is not None:
        assert out["torque_Nm"].map(math.isfinite).all()
        assert out["torque_Nm"].between(0.0, MAX_TORQUE).all()
        assert out[["phase", "phase_rate", "stride_length_m", "incline_deg"]].map(math.isfinite).all().all()


def test_huge_values_give_finite_torques(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    n = 400
    t = [0.01 * k for k in range(n)]
    table = pd.DataFrame({"time_s": t, **{c: [10.0 * math.sin(6 * x) for x in t] for c in schema.REPLAY_SIGNALS}})
    table.loc[100:110, "foot_vel_dps"] = 1e308
    table.loc[200:210, "heel_up_m"] = -1e308
    code, out = _replay(tmp_path, table, capsys)
    assert code == 0 and out is not None
    assert out["torque_Nm"].map(math.isfinite).all() and out["torque_Nm"].between(0, MAX_TORQUE).all()


@pytest.mark.parametrize("times", [[1e-320 * k for k in range(1, 50)], [1e300 * k for k in range(1, 50)]])
def test_denormal_or_huge_times_are_refused_with_a_reason(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], times: list[float]
) -> None:
    table = pd.DataFrame({"time_s": times, "foot_angle_deg": [1.0] * len(times)})
    src, out = tmp_path / "in.csv", tmp_path / "out.csv"
    table.to_csv(src, index=False, float_format="%.17g")
    assert main(["replay", str(src), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "time_s" in err and "median time step" in err and not out.exists()
