"""The live path under faults: bad frames, clock jumps, reboots, failures, against the real app.

Each test reproduces a failure seen when gaitscope was probed as a faulty device would probe it, and
checks the behaviour wanted instead: the torque on the wire is always finite and within the session's
bound, and a session never dies silently.
"""

from __future__ import annotations

import json
import math
import sqlite3
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from starlette.websockets import WebSocketDisconnect

from gaitscope.sessions.schema import SENSOR_LIMITS
from gaitscope.sessions.synth.trials import replay_input, sensor_trial
from tests.device_tokens import device_path
from tests.waiting import wait_until

MAX_TORQUE = 20.0


def _subject(client: TestClient) -> int:
    body = {"code": f"F{time.monotonic_ns() % 10**8}", "leg_length_m": 0.9, "mass_kg": 80}
    r = client.post("/api/subjects", json=body)
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def _device_session(client: TestClient, rate_hz: float = 1000.0, **settings: float) -> int:
    body = {
        "subject_id": _subject(client),
        "source": {"kind": "device", "rate_hz": rate_hz},
        "settings": {"max_torque_Nm": MAX_TORQUE, **settings},
    }
    r = client.post("/api/sessions", json=body)
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def _walk(k: int, t: float) -> dict[str, Any]:
    """A plausible frame: the foot and shank swinging at one stride per second."""
    w = 2 * math.pi * t
    return {
        "type": "frame",
        "seq": k,
        "t": t,
        "foot_angle_deg": 25 * math.sin(w),
        "foot_vel_dps": 25 * 2 * math.pi * math.cos(w),
        "shank_angle_deg": 20 * math.sin(w - 0.4),
        "shank_vel_dps": 20 * 2 * math.pi * math.cos(w - 0.4),
    }


@contextmanager
def _device(client: TestClient, sid: int) -> Iterator[Any]:
    with client.websocket_connect(device_path(client, sid)) as ws:
        yield ws


def _send(ws: Any, frame: dict[str, Any] | str) -> dict[str, Any]:
    ws.send_text(frame if isinstance(frame, str) else json.dumps(frame))
    reply: dict[str, Any] = json.loads(ws.receive_text())
    if reply["type"] == "torque":
        assert isinstance(reply["torque_Nm"], float) and 0.0 <= reply["torque_Nm"] <= MAX_TORQUE, reply
    return reply


def _walk_torques(ws: Any, t0: float, n: int, seq0: int = 0) -> list[float]:
    replies = [_send(ws, _walk(seq0 + k, t0 + 0.005 * k)) for k in range(n)]
    assert all(r["type"] == "torque" for r in replies), [r for r in replies if r["type"] != "torque"][:3]
    return [r["torque_Nm"] for r in replies]


def _state(client: TestClient, sid: int) -> str:
    return str(client.get(f"/api/sessions/{sid}").json()["state"])


# --- 1. the torque is always finite and bounded ---------------------------------------------------

JSON_NUMBER = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True),
    st.floats(-1e3, 1e3),
    st.integers(-(2**70), 2**70),
)
FRAME = st.fixed_dictionaries(
    {"type": st.just("frame"), "seq": st.integers(0, 2**40), "t": JSON_NUMBER},
    optional={name: st.one_of(JSON_NUMBER, st.none()) for name in SENSOR_LIMITS}
    | {"heel_strike": st.one_of(st.booleans(), st.none()), "sent_ns": st.integers(-5, 2**64)},
)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(frames=st.lists(FRAME, min_size=1, max_size=30))
def test_any_frames_on_the_wire_give_a_bounded_torque_or_a_notice(client: TestClient, frames: list[dict]) -> None:
    sid = _device_session(client)
    with _device(client, sid) as ws:  # NaN and Infinity go out as JSON's NaN / Infinity tokens
        for frame in frames:
            reply = _send(ws, json.dumps(frame))
            assert reply["type"] in ("torque", "error"), reply
        assert _walk_torques(ws, 1e6, 5, 10**6)  # a sane frame after all that is still answered
    assert _state(client, sid) == "running"
    client.post(f"/api/sessions/{sid}/stop")


def test_one_huge_velocity_does_not_silence_the_torque(client: TestClient) -> None:
    sid = _device_session(client, torque_gain=1.0)
    with _device(client, sid) as ws:
        _walk_torques(ws, 0.0, 50)
        assert _send(ws, {**_walk(50, 0.25), "foot_vel_dps": 1e50})["type"] == "torque"
        torques = _walk_torques(ws, 0.255, 600, 51)
    assert max(torques) > 1.0
    health = client.app.state.ctx.manager.get(sid).health()  # type: ignore[attr-defined]
    assert health.implausible == 1


def test_nan_time_first_then_a_jump_then_normal(client: TestClient) -> None:
    sid = _device_session(client)
    with _device(client, sid) as ws:
        for token in ("NaN", "Infinity", "-Infinity", "1e400"):
            reply = _send(ws, '{"type": "frame", "seq": 0, "t": ' + token + ', "foot_angle_deg": 1.0}')
            assert reply["type"] == "error" and reply["kind"] == "invalid" and reply["detail"][0]["loc"] == ["t"]
        _walk_torques(ws, 5.0, 100)
        assert _send(ws, _walk(100, 1e5))["type"] == "torque"  # an implausible jump: resynchronised
        _walk_torques(ws, 5.5, 300, 101)  # and back: resynchronised again, never "does not increase"

    def resynchronised() -> bool:  # the notes are stored off the loop: on a loaded machine, after the last reply
        return any("resynchronised" in e["text"] for e in client.get(f"/api/sessions/{sid}/events").json())

    wait_until(resynchronised, what="the resynchronisation's event")
    assert client.post(f"/api/sessions/{sid}/stop").json()["state"] == "stopped"


def test_a_device_that_reboots_gets_torque_and_the_session_stops_cleanly(client: TestClient) -> None:
    sid = _device_session(client)
    with _device(client, sid) as ws:
        _walk_torques(ws, 1000.0, 400)
    with _device(client, sid) as ws:  # rebooted: its clock restarts at 0
        assert len(_walk_torques(ws, 0.0, 400)) == 400
    r = client.post(f"/api/sessions/{sid}/stop")
    assert r.status_code == 200 and r.json()["state"] == "stopped"
    trials = client.get(f"/api/trials?session_id={sid}").json()
    assert [t["status"] for t in trials] == ["finished"] and trials[0]["samples"] == 800


def test_binary_and_malformed_messages_get_a_notice(client: TestClient) -> None:
    sid = _device_session(client)
    with _device(client, sid) as ws:
        ws.send_bytes(b"\x00\x01")
        assert json.loads(ws.receive_text())["kind"] == "binary"
        assert _send(ws, "{not json")["kind"] == "invalid"
        assert _send(ws, {"type": "frame", "seq": -1, "t": 0.0})["kind"] == "invalid"
        _walk_torques(ws, 0.0, 10)


def test_a_processing_error_fails_the_session_with_an_event(client: TestClient) -> None:
    sid = _device_session(client)
    runtime = client.app.state.ctx.manager.get(sid)  # type: ignore[attr-defined]

    def broken(*_: object) -> None:
        raise RuntimeError("injected fault")

    with _device(client, sid) as ws:
        _walk_torques(ws, 0.0, 20)
        runtime.estimator.step = broken
        ws.send_text(json.dumps(_walk(20, 0.1)))
        with pytest.raises(WebSocketDisconnect) as exc:
            ws.receive_text()
    assert exc.value.code == 1011
    assert _state(client, sid) == "failed"
    events = [e["text"] for e in client.get(f"/api/sessions/{sid}/events").json()]
    assert any("session failed" in e and "injected fault" in e for e in events)
    assert [t["status"] for t in client.get(f"/api/trials?session_id={sid}").json()] == ["finished"]


def test_a_source_that_fails_ends_the_session_as_failed(client: TestClient, tmp_path: Any) -> None:
    sid = _device_session(client)
    with _device(client, sid) as ws:
        _walk_torques(ws, 0.0, 50)
    client.post(f"/api/sessions/{sid}/stop")
    trial = client.get(f"/api/trials?session_id={sid}").json()[0]
    (client.app.state.ctx.settings.data_dir / trial["path"]).write_bytes(b"\x89MCAP0\r\n garbage")  # type: ignore[attr-defined]
    r = client.post("/api/sessions", json={"subject_id": 1, "source": {"kind": "replay", "trial_id": trial["id"]}})
    assert r.status_code == 201
    replay = r.json()["id"]
    wait_until(lambda: _state(client, replay) != "running", 10.0, "the replay of a broken MCAP to end")
    assert _state(client, replay) == "failed"
    texts = [e["text"] for e in client.get(f"/api/sessions/{replay}/events").json()]
    assert any(t.startswith("session failed") for t in texts)
    assert all(str(client.app.state.ctx.settings.data_dir) not in t for t in texts)  # type: ignore[attr-defined]
    assert [t["status"] for t in client.get(f"/api/trials?session_id={replay}").json()] == ["finished"]


# --- 3. a change takes effect only when it is recorded --------------------------------------------


def test_a_change_the_database_refuses_is_not_applied(client: TestClient, monkeypatch: pytest.MonkeyPatch) -> None:
    sid = _device_session(client)
    runtime = client.app.state.ctx.manager.get(sid)  # type: ignore[attr-defined]
    store = client.app.state.ctx.store  # type: ignore[attr-defined]

    def full(*_: object, **__: object) -> None:
        raise sqlite3.OperationalError("database or disk is full")

    with monkeypatch.context() as m:
        m.setattr(store, "change_settings", full)
        r = client.patch(f"/api/sessions/{sid}/settings", json={"torque_gain": 0.5})
        assert r.status_code == 507 and "not applied" in r.json()["detail"] and "disk is full" in r.json()["detail"]
    assert runtime.estimator.settings.torque_gain == 1.0
    assert client.get(f"/api/sessions/{sid}").json()["settings"]["torque_gain"] == 1.0
    assert not [e for e in client.get(f"/api/sessions/{sid}/events").json() if e["kind"] == "setting"]
    r = client.patch(f"/api/sessions/{sid}/settings", json={"torque_gain": 0.5})  # rate-checked against 1.0
    assert r.status_code == 200 and runtime.estimator.settings.torque_gain == 0.5


def test_a_new_session_at_high_assistance_ramps_up(client: TestClient) -> None:
    """Reproduces: a session created at gain 3 and 80 N m applied them from the first sample."""
    sid = _device_session(client, torque_gain=3.0, max_torque_Nm=80.0)
    sensors, _, _ = sensor_trial([(1.2, 0.0, 12)], rate_hz=200.0)
    walk = replay_input(sensors)
    torques = []
    with _device(client, sid) as ws:
        for k in range(2000):
            frame = {"type": "frame", "seq": k, "t": float(walk.time_s[k])}
            frame |= {name: float(v[k]) for name, v in walk.signals.items()}
            ws.send_text(json.dumps(frame))
            reply = json.loads(ws.receive_text())
            assert reply["type"] == "torque" and 0.0 <= reply["torque_Nm"] <= 80.0
            torques.append(reply["torque_Nm"])
    for k, tau in enumerate(torques):
        assert tau <= 10.0 * (0.005 * k) + 1e-9  # at most the 10 N m/s rate limit of the bound
    assert max(torques[1600:]) > 1.5 * max(torques[:200]) > 0  # ramped up, not stepped
    events = [e["text"] for e in client.get(f"/api/sessions/{sid}/events").json()]
    assert any(e.startswith("soft start") for e in events)


# --- 5. no 500s -------------------------------------------------------------------------------------


@pytest.mark.parametrize("body", ['{"torque_gain": NaN}', '{"torque_gain": Infinity}', '{"torque_gain": 1e999}'])
def test_non_finite_json_is_a_422(client: TestClient, body: str) -> None:
    sid = _device_session(client)
    r = client.patch(f"/api/sessions/{sid}/settings", content=body, headers={"content-type": "application/json"})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"][-1] == "torque_gain"


@pytest.mark.parametrize(
    "url",
    ["/api/sessions/{big}", "/api/trials/{big}", "/api/subjects/{big}", "/api/sessions/{big}/events",
     "/api/sessions?subject_id={big}", "/api/trials?session_id={big}"],
)  # fmt: skip
def test_ids_beyond_sqlite_are_a_clear_4xx(client: TestClient, url: str) -> None:
    r = client.get(url.format(big=2**70))
    assert r.status_code in (404, 422) and "detail" in r.json()


def test_a_disk_running_out_warns_then_stops_cleanly(client: TestClient) -> None:
    """Reproduces: with the disk full a session's task died, it stayed "running" and lost its last seconds."""
    sid = _device_session(client, rate_hz=200.0)
    runtime = client.app.state.ctx.manager.get(sid)  # type: ignore[attr-defined]
    level = {"now": "low"}
    runtime.disk_check = lambda: level["now"]
    runtime.disk_room = lambda: 100 * 2**20  # 100 MiB until the stop
    with _device(client, sid) as ws:
        _walk_torques(ws, 0.0, 100)
        wait_until(lambda: runtime.disk == "low", 5.0, "the disk seen low")
        assert runtime.health().disk == "low"
        left = 100 * 2**20 / runtime.disk_rate.bytes_per_s / 60  # the session's rate: its stack and 200 Hz
        assert runtime.health().disk_minutes == pytest.approx(left, abs=0.1) and 5 < left < 30
        level["now"] = "critical"
        wait_until(lambda: _state(client, sid) != "running", 5.0, "the session stopped by a critical disk")
        ws.send_text(json.dumps(_walk(100, 0.5)))
        with pytest.raises(WebSocketDisconnect):  # the device is told the session ended
            while True:
                json.loads(ws.receive_text())
    assert _state(client, sid) == "stopped"
    texts = [e["text"] for e in client.get(f"/api/sessions/{sid}/events").json()]
    assert any("almost full" in t for t in texts)
    [low] = [t for t in texts if t.startswith("disk space is low")]
    assert low.startswith(f"disk space is low: about {left:.0f} min of recording left at this session's ")
    assert "(undeclared channels at 200 Hz, " in low and "free space on the server's data disk" in low
    trial = client.get(f"/api/trials?session_id={sid}").json()[0]
    assert trial["status"] == "finished" and trial["samples"] == 100
    r = client.post(f"/api/sessions/{sid}/recording", json={"action": "start"})
    assert r.status_code == 409  # not running any more


def test_a_trial_still_recording_cannot_be_replayed(client: TestClient) -> None:
    """Reproduces: a replay of an unfinished trial stayed "running" forever."""
    sid = _device_session(client)
    trial = client.get(f"/api/trials?session_id={sid}").json()[0]
    assert trial["status"] == "recording"
    body = {"subject_id": 1, "source": {"kind": "replay", "trial_id": trial["id"]}}
    r = client.post("/api/sessions", json=body)
    assert r.status_code == 409
    assert r.json()["detail"] == f"trial {trial['id']} is still recording; it cannot be replayed"


def test_a_recording_that_cannot_be_finished_is_recovered_not_left_unindexed(client: TestClient) -> None:
    sid = _device_session(client)
    runtime = client.app.state.ctx.manager.get(sid)  # type: ignore[attr-defined]
    with _device(client, sid) as ws:
        _walk_torques(ws, 0.0, 400)

    recorder = runtime.recorder

    def full() -> None:  # the index cannot be written: the file is left as a crash would leave it
        recorder._file.close()
        raise OSError(28, "No space left on device")

    recorder.finish = full
    assert client.post(f"/api/sessions/{sid}/stop").json()["state"] == "stopped"
    trial = client.get(f"/api/trials?session_id={sid}").json()[0]
    assert trial["status"] == "recovered"
    series = client.get(f"/api/trials/{trial['id']}/series?max_points=5000").json()
    assert len(series["t"]) >= 200  # what was flushed before the failure is there, and reviewable
    texts = [e["text"] for e in client.get(f"/api/sessions/{sid}/events").json()]
    assert any("could not be finished (No space left on device): recovered" in t for t in texts)
