"""Speed-change intent, live and in review, through the real app: a device session whose walker speeds up
records one ``intent`` event per detected change (stored, sent to the browsers, on the MCAP ``/events``),
and a review gets the intent over time, or the names of the channels a trial lacks for it."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from gaitscope.sessions.formats.mcap_io import read_events, read_messages
from gaitscope.sessions.live.sources import frames_from_table
from gaitscope.sessions.registry import DECLARED
from gaitscope.sessions.synth.trials import replay_columns, sensor_trial
from tests.device_tokens import device_path
from tests.uploads import upload

#: Channels of the centre of mass relative to the stance foot, which a replay CSV does not have.
COM = ("com_forward_m", "com_up_m", "com_forward_vel_m_s", "com_up_vel_m_s")  # required (lateral: optional)


def _subject(client: TestClient) -> int:
    r = client.post("/api/subjects", json={"code": "I01", "leg_length_m": 0.9, "mass_kg": 70.0})
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def _onsets(outputs: list[tuple[float, dict[str, Any]]]) -> list[tuple[float, float]]:
    """``(t, code)`` where the recorded intent class changes to +1 or -1."""
    out, last = [], 0.0
    for t, values in outputs:
        code = values["intent_code"]
        if code is None:
            continue
        if code != last and code in (1.0, -1.0):
            out.append((t, code))
        last = code
    return out


def test_a_walker_speeding_up_is_an_intent_event_live_in_the_recording_and_in_review(client: TestClient) -> None:
    ctx = client.app.state.ctx  # type: ignore[attr-defined]
    source = {"kind": "device", "rate_hz": 1000.0}  # frames as fast as the socket takes them, none dropped
    settings = {"estimators": ["phase_ekf", "intent"]}
    r = client.post("/api/sessions", json={"subject_id": _subject(client), "source": source, "settings": settings})
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    sensors, _, _ = sensor_trial([(1.0, 0.0, 6), (1.3, 0.0, 6)], rate_hz=100.0)
    speed = sensors["gt_speed_m_s"].to_numpy()
    t_change = float(sensors["time_s"].to_numpy()[np.argmax(speed > 1.01)])  # the walker starts to speed up
    browser_events = []
    with (
        client.websocket_connect(f"/ws/sessions/{sid}?max_rate_hz=10&batch_ms=100") as browser,
        client.websocket_connect(device_path(client, sid)) as device,
    ):
        assert json.loads(browser.receive_text())["type"] == "hello"
        for k, frame in enumerate(frames_from_table(sensors)):
            values = frame.model_dump(exclude_none=True, exclude={"seq", "sent_ns"})
            device.send_text(json.dumps({"type": "frame", **values, "seq": k}))
            assert json.loads(device.receive_text())["type"] == "torque"
        stored = [e for e in client.get(f"/api/sessions/{sid}/events").json() if e["kind"] == "intent"]
        deadline = time.monotonic() + 10
        while len(browser_events) < len(stored) and time.monotonic() < deadline:  # health comes once a second
            msg = json.loads(browser.receive_text())
            if msg["type"] == "event" and msg["event"]["kind"] == "intent":
                browser_events.append(msg["event"])
    assert client.post(f"/api/sessions/{sid}/stop").status_code == 200
    assert browser_events == stored

    # the walker sped up: the first event after it is an onset of speeding up, within two steps. (The filter's
    # first intent, a step after it starts from desired = actual speed, is its own convergence: an event too.)
    first = next(e for e in stored if e["t"] > t_change)
    assert first["text"].startswith("speeding up: desired ") and first["after"] - first["before"] > 0.15
    assert first["t"] < t_change + 2.5
    assert first["field"] == "desired_speed_m_s" and first["actor"] == "system"

    # one event per change of the class (at the sample where it changed), not one per sample or per step
    [trial] = client.get(f"/api/trials?session_id={sid}").json()
    path = Path(ctx.settings.data_dir) / trial["path"]
    recorded = [(m["t"], m["values"]) for _, _, m in read_messages(path, ["/estimators/intent"])]
    assert len(recorded) == trial["samples"]
    onsets = _onsets(recorded)
    assert [(e["t"], 1.0 if e["text"].startswith("speeding up") else -1.0) for e in stored] == onsets
    assert 1 <= len(onsets) <= 2 * 12  # at most one per mid-stance (12 strides, two mid-stances each)
    at = {t: v for t, v in recorded}
    assert [e["after"] for e in stored] == pytest.approx([at[e["t"]]["desired_speed_m_s"] for e in stored], abs=5e-4)

    # on the recording's /events as foxglove.Event, fields and all
    in_file = [e for e in read_events(path) if e["kind"] == "intent"]
    assert [(e["id"], e["t"], e["text"], e["before"], e["after"]) for e in in_file] == [
        (e["id"], e["t"], e["text"], e["before"], e["after"]) for e in stored
    ]
    assert all(e["log_time_ns"] == in_file[0]["log_time_ns"] + round((e["t"] - in_file[0]["t"]) * 1e9) for e in in_file)

    # review: the recorded intent over time, decimated by the server, and within a window
    review = client.get(f"/api/trials/{trial['id']}/intent?max_points=100").json()
    assert review["recorded"] is True and review["missing"] == []
    series = review["series"]
    assert set(series) == {"t", *(o for o, _ in DECLARED["intent"].outputs)}
    assert 50 <= len(series["t"]) <= 100 and all(len(c) == len(series["t"]) for c in series.values())
    assert max(series["desired_speed_m_s"]) == max(v["desired_speed_m_s"] for _, v in recorded)  # peaks kept
    assert min(series["speed_m_s"]) == min(v["speed_m_s"] for _, v in recorded)
    window = client.get(f"/api/trials/{trial['id']}/intent?t0=5&t1=6&max_points=1000").json()["series"]
    assert window["t"] == [t for t, _ in recorded if 5.0 - 1e-9 <= t <= 6.0 + 1e-9]


def test_review_names_the_channels_a_trial_lacks_for_the_intent_estimator(client: TestClient, tmp_path: Path) -> None:
    sensors, _, _ = sensor_trial([(1.0, 0.0, 4)], rate_hz=100.0)
    table = replay_columns(sensors)  # the replay CSV: foot and shank angles, heel position: no centre of mass
    path = tmp_path / "no_com.csv"
    table.to_csv(path, index=False, float_format="%.6f")
    trial_id = upload(client, path, _subject(client))["id"]

    review = client.get(f"/api/trials/{trial_id}/intent").json()
    missing = [c for c in DECLARED["intent"].inputs if c not in table.columns]
    assert review == {"recorded": False, "missing": missing, "series": {}}
    assert set(COM) <= set(missing)
    # an import estimates, records every output, but logs no events: none about intent either
    assert not [e for e in client.get(f"/api/trials/{trial_id}/events").json() if e["kind"] == "intent"]
    assert client.get("/api/trials/999/intent").status_code == 404
