"""A replay CSV of raw IMU signals: uploaded, the stack's IMU front end derives the angles; the command
line's seed 000 replay refuses it with a message that says where to take it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient

from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.formats.mcap_io import read_messages
from gaitscope.sessions.formats.replay_io import RAW_IMUS, read_replay_csv
from gaitscope.sessions.synth.trials import sensor_trial
from tests.uploads import upload


def _raw_imu_csv(tmp_path: Path) -> Path:
    sensors, _, _ = sensor_trial([(1.1, 0.0, 12)], rate_hz=100.0)
    columns = ["time_s", *RAW_IMUS["foot"], *RAW_IMUS["shank"]]
    path = tmp_path / "raw_imu.csv"
    sensors[columns].to_csv(path, index=False, float_format="%.6f")
    return path


def test_an_uploaded_raw_imu_csv_is_estimated_through_the_imu_front_end(client: TestClient, tmp_path: Path) -> None:
    subject = client.post("/api/subjects", json={"code": "R01", "leg_length_m": 0.9, "mass_kg": 70.0}).json()
    trial = upload(client, _raw_imu_csv(tmp_path), subject["id"])
    assert trial["samples"] > 1000
    series = client.get(f"/api/trials/{trial['id']}/series?max_points=2000").json()
    phase = np.array([p for p in series["phase"] if p is not None])
    assert len(phase) > 100 and np.ptp(phase) > 0.8  # the phase sweeps whole cycles: it tracks the walk
    choices = client.get(f"/api/trials/{trial['id']}/estimators").json()
    assert {"imu_foot", "imu_shank", "phase_ekf"} <= set(choices["recorded"])
    recording = next((tmp_path / "data").rglob("*.mcap"))  # the client's data folder
    first = next(m for _, _, m in read_messages(recording, ["/sensor"]))
    assert "imu_foot_gyro_z_dps" in first  # the frames keep the raw channels


def test_the_command_line_replay_says_where_raw_imu_files_go(tmp_path: Path) -> None:
    hint = r"raw IMU columns \(foot, shank\).*--estimators imu_foot,imu_shank,phase_ekf"
    with pytest.raises(DataFormatError, match=hint):
        read_replay_csv(_raw_imu_csv(tmp_path))
    assert set(read_replay_csv(_raw_imu_csv(tmp_path), ["imu_shank", "phase_ekf"]).signals) == {
        *RAW_IMUS["foot"],
        *RAW_IMUS["shank"],
    }
