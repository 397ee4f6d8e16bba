"""The IMU study's table: one subject, the front end's rows and the baselines."""

from __future__ import annotations

from gaitscope.sessions.offline.imu_study import ImuStudy, run_study, to_markdown


def test_the_front_end_beats_its_baselines_and_the_table_names_every_method() -> None:
    study = run_study(subjects=1, ahrs_subjects=0)
    assert isinstance(study, ImuStudy)
    e = study.errors
    rmse = e.groupby(["method", "segment"])["rmse_deg"].mean()
    for segment in ("foot", "shank", "thigh"):
        assert rmse["cf", segment] < rmse["accel", segment] and rmse["cf", segment] < rmse["gyro", segment]
    assert set(e["method"]) == {"cf", "fusion", "gyro", "accel"}  # ahrs_subjects=0: no Madgwick / Mahony rows
    assert 0.55 < study.toe_off_phase < 0.72
    md = to_markdown(study)
    assert "| cf | 1 |" in md and "| 1 | -10 |" in md
