"""Issue #25: what a lab's own CSV can feed, through the real upload API. A shank-only walk (one shank IMU's raw
columns, or a shank angle) uploads and runs the phase EKF; a walk with thigh columns feeds the fingerprint
filters; every other column is listed back; a file that feeds no phase estimator, or whose values are not in
the units or signs their names say, is refused (422) naming what is wrong, and nothing is stored."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from fastapi.testclient import TestClient

from gaitscope.sessions.formats.replay_io import RAW_IMUS
from gaitscope.sessions.synth.sensors import SensorNoise
from gaitscope.sessions.synth.trials import sensor_trial
from tests.uploads import send, upload


@pytest.fixture(scope="module")
def walk() -> pd.DataFrame:
    """16 strides at 1.1 m/s. The shank angle's noise is an IMU's (1 deg), not the default cohort's 7 deg of
    white noise (seed 000's measurement covariance, a model error): an angle's velocity is derived by backward
    difference, as live, and 7 deg of white noise at 100 Hz makes ~1000 deg/s of it (the phase EKF on such a
    shank angle alone scores 24 % phase RMSE; on this one 0.7 %: docs/api.md, CSV columns)."""
    sensors, _, _ = sensor_trial([(1.1, 0.0, 16)], rate_hz=100.0, noise=SensorNoise(shank_angle_deg=1.0))
    return sensors


def _subject(client: TestClient) -> int:
    r = client.post("/api/subjects", json={"code": "F01", "leg_length_m": 0.9, "mass_kg": 70.0})
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def _csv(tmp_path: Path, table: pd.DataFrame, name: str) -> Path:
    path = tmp_path / name
    table.to_csv(path, index=False, float_format="%.6f")
    return path


def _feeds(trial: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {e["name"]: e for e in trial["report"]["estimators"]}


def _phase_rmse(client: TestClient, trial: dict[str, Any], truth: pd.DataFrame) -> float:
    """Phase RMSE (cycles, wrapped) of the trial's recorded phase against the walk's ground truth, after
    the first 3 s."""
    r = client.get(f"/api/trials/{trial['id']}/series?max_points=5000")
    assert r.status_code == 200, r.text
    series = r.json()
    t = np.asarray(series["t"], dtype=float)
    est = np.asarray([np.nan if p is None else p for p in series["phase"]], dtype=float)
    gt = np.interp(t, truth["time_s"], np.unwrap(truth["gt_phase"] * 2 * np.pi) / (2 * np.pi)) % 1.0
    keep = (t > 3.0) & np.isfinite(est)
    err = (est[keep] - gt[keep] + 0.5) % 1.0 - 0.5
    return float(np.sqrt(np.mean(err**2)))


def test_a_shank_only_walk_uploads_and_runs_the_phase_ekf(
    client: TestClient, tmp_path: Path, walk: pd.DataFrame
) -> None:
    subject = _subject(client)
    # one shank IMU's raw columns: the IMU front end derives the shank angle, the phase EKF runs on it
    raw = upload(client, _csv(tmp_path, walk[["time_s", *RAW_IMUS["shank"]]], "shank_imu.csv"), subject)
    feeds = _feeds(raw)
    assert feeds["imu_shank"]["ran"] and feeds["phase_ekf"]["ran"]
    assert feeds["phase_ekf"]["derived"] == {"shank_angle_deg": ["imu_shank"]}
    assert not feeds["fp_avg"]["feedable"] and feeds["fp_avg"]["missing"][0] == "thigh_angle_deg"
    # a shank angle column: its velocity derived as live, the phase EKF on it
    angle = upload(client, _csv(tmp_path, walk[["time_s", "shank_angle_deg"]], "shank_angle.csv"), subject)
    assert angle["report"]["channels"] == ["shank_angle_deg"] and angle["report"]["derived"] == ["shank_vel_dps"]
    assert _feeds(angle)["phase_ekf"]["ran"] and not _feeds(angle)["hs_detector"]["feedable"]
    for trial in (raw, angle):
        assert _phase_rmse(client, trial, walk) < 0.03, trial["name"]  # it tracks the walk's phase


def test_thigh_columns_feed_the_fingerprint_filters_and_other_columns_are_listed(
    client: TestClient, tmp_path: Path, walk: pd.DataFrame
) -> None:
    table = walk[["time_s", "foot_angle_deg", "shank_angle_deg", "thigh_angle_deg", "heel_strike"]].copy()
    table["Notes"] = "ok"
    table["gt_phase"] = walk["gt_phase"]
    trial = upload(client, _csv(tmp_path, table, "overground.csv"), _subject(client))
    report = trial["report"]
    assert report["format"] == "replay_csv" and report["ignored"] == ["Notes", "gt_phase"]
    assert report["channels"] == ["foot_angle_deg", "shank_angle_deg", "thigh_angle_deg", "heel_strike"]
    feeds = _feeds(trial)
    assert feeds["fp_avg"]["ran"] and feeds["fp_gf"]["ran"] and feeds["phase_ekf"]["ran"]
    r = client.post(f"/api/trials/{trial['id']}/rerun?max_points=500", json={"estimators": ["fp_avg", "fp_gf"]})
    assert r.status_code == 200, r.text
    for name in ("fp_avg", "fp_gf"):
        phase = np.array([p for p in r.json()[f"{name}.phase"] if p is not None])
        assert phase.size > 100 and np.ptp(phase) > 0.8, name  # whole cycles: the filter tracks the walk


@pytest.mark.parametrize(
    ("columns", "change", "words"),
    [
        (["time_s", "belt_speed_m_s"], None, "feed no estimator of the gait phase"),
        (["time_s", "foot_angle_deg", "heel_forward_m"], ("heel_forward_m", 1000.0), "is the column in m?"),
        (["time_s", "shank_angle_deg", "knee_angle_deg"], ("knee_angle_deg", -1.0), "is the column's sign reversed?"),
        (["time_s", "foot_angle_deg"], ("foot_angle_deg", -1.0), "the foot angle reaches +"),
    ],
)
def test_a_file_that_cannot_be_estimated_is_refused_naming_why_and_nothing_is_stored(
    client: TestClient,
    tmp_path: Path,
    walk: pd.DataFrame,
    columns: list[str],
    change: tuple[str, float] | None,
    words: str,
) -> None:
    table = walk[columns].copy()
    if change is not None:
        table[change[0]] *= change[1]
    before = client.get("/api/trials").json()
    r = send(client, "lab.csv", _csv(tmp_path, table, "lab.csv").read_bytes(), _subject(client))
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert detail.startswith("file lab.csv") and words in detail, detail
    if change is not None:
        assert f"column '{change[0]}'" in detail
    else:
        assert "phase_ekf needs foot_angle_deg or shank_angle_deg" in detail
    assert client.get("/api/trials").json() == before


def test_a_real_shank_imu_walk_uploads_and_runs_the_phase_ekf_through_the_imu_front_end(
    client: TestClient, tmp_path: Path
) -> None:
    """A real walk of one Xsens IMU on the lower leg (scikit-kinematics' test data on PyPI), its raw channels
    as a CSV: the IMU front end derives the shank angle, the phase EKF runs on it. No ground truth comes with
    the file: the heel strikes must come once a stride, evenly, and the phase rate agree with them."""
    from gaitscope.sessions.offline.lab_files import xsens_lower_leg, xsens_shank_table

    path = _csv(tmp_path, xsens_shank_table(xsens_lower_leg()), "xsens_shank.csv")
    trial = upload(client, path, _subject(client))
    assert [e["name"] for e in trial["report"]["estimators"] if e["ran"]] == ["imu_shank", "phase_ekf", "tbe"]
    series = client.get(f"/api/trials/{trial['id']}/series?max_points=5000").json()
    t = np.asarray(series["t"])
    strikes = t[np.asarray(series["heel_strike"], dtype=bool)]
    strides = np.diff(strikes)
    assert 18 <= strikes.size <= 22 and strides.std() / strides.mean() < 0.1, strikes  # ~1.27 s apart
    rate = np.nanmedian(np.asarray([np.nan if r is None else r for r in series["phase_rate"]], dtype=float))
    assert rate == pytest.approx(1.0 / np.median(strides), rel=0.05)


def test_a_real_walks_thigh_columns_as_a_csv_run_the_fingerprint_filters(client: TestClient, tmp_path: Path) -> None:
    """The real Vicon treadmill walk's segment angles (its C3D read by gaitscope) written as the CSV a lab's
    own pipeline would export: the thigh columns feed fp_avg and fp_gf, whose phases sweep every stride."""
    from gaitscope.sessions.formats.c3d import c3d_frames
    from tests.real_files import treadmill_walk_c3d

    columns = ["thigh_angle_deg", "shank_angle_deg", "foot_angle_deg", "heel_strike"]
    rows = [{"time_s": f.t, **{c: getattr(f, c) for c in columns}} for f in c3d_frames(treadmill_walk_c3d(), "w")]
    table = pd.DataFrame(rows).dropna()
    table["heel_strike"] = table["heel_strike"].astype(int)
    trial = upload(client, _csv(tmp_path, table, "vicon_walk.csv"), _subject(client))
    feeds = _feeds(trial)
    assert feeds["fp_avg"]["ran"] and feeds["fp_gf"]["ran"] and trial["report"]["ignored"] == []
    r = client.post(f"/api/trials/{trial['id']}/rerun?max_points=2000", json={"estimators": ["fp_avg", "fp_gf"]})
    assert r.status_code == 200, r.text
    for name in ("fp_avg", "fp_gf"):
        phase = np.array([np.nan if p is None else p for p in r.json()[f"{name}.phase"]], dtype=float)
        assert np.isfinite(phase).mean() > 0.95 and np.nanmax(phase) - np.nanmin(phase) > 0.9, name
