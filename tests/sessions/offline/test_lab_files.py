"""``gaitscope labfiles``: a real Vicon walk (a PyPI package's test data) through every estimator of the gait
phase it feeds, scored against the lab's own Foot Strike events."""

from __future__ import annotations

import pytest

from gaitscope.sessions.formats.models import default_model_path, load_model
from gaitscope.sessions.offline.lab_files import c3d_events, c3d_subject, score_c3d
from tests.real_files import treadmill_walk_c3d


def test_the_real_treadmill_walk_is_scored_against_its_own_events() -> None:
    path = treadmill_walk_c3d()
    events = c3d_events(path)
    assert events[("Right", "Foot Strike")].size == 11 and events[("Left", "Foot Off")].size == 11
    assert events[("Right", "Foot Strike")][0] == pytest.approx(0.06, abs=1e-6)  # 0.50 s less the first frame's
    leg, mass = c3d_subject(path) or (0.0, 0.0)
    assert (leg, mass) == (pytest.approx(0.904685, abs=1e-6), pytest.approx(55.3262, abs=1e-4))
    scores = {s.estimator: s for s in score_c3d(path, load_model(default_model_path())[0], leg, mass)}
    assert set(scores) == {"phase_ekf", "tbe", "hs_backup", "fp_avg", "fp_gf", "gp_ekf"}  # fp_ls: no calibration
    for name in ("phase_ekf", "fp_avg", "fp_gf", "tbe", "gp_ekf"):
        assert scores[name].samples == 1206 and scores[name].phase_rmse < 0.05, scores[name]
    ekf = scores["phase_ekf"]
    assert ekf.strikes == ekf.lab_strikes == 11 and ekf.strike_error_ms is not None and ekf.strike_error_ms < 20.0


def test_the_command_prints_a_row_per_estimator(capsys: pytest.CaptureFixture[str]) -> None:
    from gaitscope.server.cli import main

    assert main(["labfiles", str(treadmill_walk_c3d())]) == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines()[1:]]
    ekf = next(r for r in rows if r[1] == "phase_ekf")
    assert ekf[2] == "1206" and ekf[3] == "1.85%" and ekf[4:7] == ["11", "of", "11"]


def test_the_real_shank_imu_walk_gives_regular_heel_strikes_and_a_phase_rate_that_agrees() -> None:
    from gaitscope.sessions.offline.lab_files import score_shank_imu, xsens_lower_leg, xsens_shank_table

    walk = score_shank_imu(xsens_shank_table(xsens_lower_leg()), load_model(default_model_path())[0], 0.9, 70.0)
    assert walk.samples == 3511 and walk.estimators == ("imu_shank", "phase_ekf", "tbe")
    assert 18 <= walk.strikes <= 22 and walk.stride_sd_s < 0.1 * walk.stride_s
    assert walk.phase_rate == pytest.approx(1.0 / walk.stride_s, rel=0.03)

