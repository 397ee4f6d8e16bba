"""IMU problems surfaced to the clinician (issue #10, section 4): the debounce of :class:`ImuWatch` on made-up
codes, then each fault injected on one IMU of a raw-IMU device session over the real websocket: an event
naming the sensor and the problem once, data health showing it, a bounded torque throughout, the session
still running, and a recovery event when the fault ends."""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from gaitscope.estimators.imu_frontend import CODES, ImuFrontEnd, imu_inputs
from gaitscope.sessions.live import manager
from gaitscope.sessions.live.imu_events import PROBLEMS, SEVERITY, ImuEvent, ImuWatch
from gaitscope.sessions.live.sources import LiveDevice, frames_from_table
from gaitscope.sessions.synth.trials import sensor_trial
from tests.device_tokens import device_path

PERIOD = 0.01
SEGMENTS = ("foot", "shank", "thigh")


def _watch(side: str | None = "right", **kw: float) -> ImuWatch:
    ends = [ImuFrontEnd(seg) for seg in SEGMENTS]
    return ImuWatch(ends, [[n for n, _ in e.outputs] for e in ends], side, **kw)


def _outputs(codes: dict[str, str]) -> list[np.ndarray]:
    """One sample's outputs of the three front ends: ``imu_code`` as given (by segment), fine otherwise."""
    return [np.array([0.0, 0.0, float(CODES.index(codes.get(seg, "")))]) for seg in SEGMENTS]


def _run(watch: ImuWatch, seconds: float, codes_at: Callable[[float], dict[str, str]]) -> list[tuple[float, ImuEvent]]:
    events = []
    for k in range(round(seconds / PERIOD)):
        t = k * PERIOD
        events += [(t, e) for e in watch.update(t, _outputs(codes_at(t)))]
    return events


def test_every_code_has_words_and_a_rank() -> None:
    assert list(PROBLEMS) == list(CODES[1:]) and sorted(SEVERITY) == sorted(CODES[1:])
    with pytest.raises(ValueError, match="onset_s must be within"):
        _watch(onset_s=2.0)
    none = ImuWatch([], [])  # a stack without front ends: no IMU line in data health
    assert not none.active and none.health() == (None, "")


def test_isolated_bad_samples_and_short_bursts_start_nothing() -> None:
    def codes(t: float) -> dict[str, str]:
        k = round(t / PERIOD)
        if k % 20 == 0:  # one sample in 20 (5 % of the time), for ever
            return {"shank": "missing"}
        if 300 <= k < 325:  # and once a burst of 0.25 s
            return {"foot": "gyro_saturated"}
        return {}

    watch = _watch()
    assert _run(watch, 6.0, codes) == []
    assert watch.health() == ("ok", "")


def test_a_lasting_problem_is_one_event_after_0_3_s_and_a_recovery_after_a_clear_second() -> None:
    watch = _watch()
    events = _run(watch, 2.0, lambda t: {"shank": "missing"} if t >= 1.0 - 1e-9 else {})
    (t_on, on), = events  # fmt: skip
    assert t_on == pytest.approx(1.29)  # 30 samples: each counts for the 10 ms since the one before
    assert on == ImuEvent(("imu_shank",), "ok", "missing", "Right shank IMU: no data for 0.3 s; shank angle held")
    assert watch.health() == ("fault", "Right shank IMU: no data for 1.0 s; shank angle held")
    # the sensor comes back at 2.5 s: the recovery is one clear second after its last missing sample
    events = []
    for k in range(200, 400):
        t = k * PERIOD
        events += [(t, e) for e in watch.update(t, _outputs({"shank": "missing"} if t < 2.5 - 1e-9 else {}))]
    (t_off, off), = events  # fmt: skip
    assert t_off == pytest.approx(3.49)
    assert off == ImuEvent(("imu_shank",), "missing", "ok", "Right shank IMU: recovered (no data for 1.5 s)")
    assert watch.health() == ("ok", "")


def test_an_intermittent_problem_is_one_episode_not_one_event_per_burst() -> None:
    """A gyro that saturates for 0.2 s of every 0.5 s (swing peaks of a too-small range) for 4 s."""
    events = _run(_watch(), 6.0, lambda t: {"foot": "gyro_saturated"} if t < 4.0 and t % 0.5 < 0.2 else {})
    assert [(e.before, e.after) for _, e in events] == [("ok", "gyro_saturated"), ("gyro_saturated", "ok")]
    assert events[0][0] == pytest.approx(0.6)  # 0.3 s within a second: the first burst's 0.19 s, the second's 0.11
    assert events[0][1].text == (
        "Right foot IMU: gyro saturated (reading at the sensor's full scale, 2000 deg/s); foot angle from the "
        "accelerometer alone"
    )
    assert events[1][0] == pytest.approx(3.69 + 1.0) and events[1][1].text == (
        "Right foot IMU: recovered (gyro saturated for 3.7 s)"
    )


def test_the_same_words_on_several_sensors_are_one_event_and_health_shows_the_worst() -> None:
    watch = _watch("left")
    events = _run(watch, 1.0, lambda t: dict.fromkeys(SEGMENTS, "sample_rate"))
    (_, on), = events  # fmt: skip
    assert on.field == "imu_foot,imu_shank,imu_thigh" and on.text == (
        "Left foot, shank and thigh IMUs: samples arrive every 10 ms, expected 10 ms; check the device's sample rate"
    )  # the made-up codes say "wrong rate" at the expected one
    for k in range(100, 200):  # the thigh's stops sending too, the shank's saturates
        watch.update(k * PERIOD, _outputs({"foot": "sample_rate", "shank": "gyro_saturated", "thigh": "missing"}))
    assert watch.health() == ("fault", "Left thigh IMU: no data for 1.0 s; thigh angle held (and 2 more IMU problems)")
    assert watch.open() == [("imu_thigh", "missing"), ("imu_shank", "gyro_saturated"), ("imu_foot", "sample_rate")]


def test_contralateral_sensors_and_an_unknown_side_are_named_plainly() -> None:
    ends = [ImuFrontEnd("shank"), ImuFrontEnd("shank_contra")]
    outs = [[n for n, _ in e.outputs] for e in ends]
    for side, names in (("right", "Right shank and left shank IMUs"), (None, "Shank and other leg's shank IMUs")):
        watch = ImuWatch(ends, outs, side)
        texts = [e.text for k in range(40) for e in watch.update(k * PERIOD, [np.array([0.0, 0.0, 4.0])] * 2)]
        assert texts == [f"{names}: samples arrive every 10 ms, expected 10 ms; check the device's sample rate"]


def test_a_failed_front_end_is_not_watched() -> None:
    watch = _watch()
    for k in range(100):
        outputs: list[np.ndarray | None] = [*_outputs({"foot": "missing"})[:2], None]
        assert all(e.estimators == ("imu_foot",) for e in watch.update(k * PERIOD, outputs))
    assert watch.open() == [("imu_foot", "missing")]


# --- a raw-IMU device session over the real websocket ------------------------------------------------------------

RATE = 100.0
MAX_TORQUE = 12.0
IMU_CHANNELS = [c for seg in SEGMENTS for c in imu_inputs(seg)]
FRONT_ENDS = {f"imu_{seg}" for seg in SEGMENTS}
#: the fault, on the shank's IMU (the sample rate: the device's), from 3.0 s to 5.5 s of a 9 s walk
FAULT = (3.0, 5.5)


def _saturated(frame: dict[str, Any]) -> dict[str, Any] | None:
    return {**frame, "imu_shank_gyro_z_dps": 2000.0}  # stuck at the gyro's full scale


def _missing(frame: dict[str, Any]) -> dict[str, Any] | None:
    return {k: v for k, v in frame.items() if not k.startswith("imu_shank_")}  # the shank's sensor stops sending


def _flipped(frame: dict[str, Any]) -> dict[str, Any] | None:
    return {**frame, "imu_shank_accel_y_m_s2": -frame["imu_shank_accel_y_m_s2"]}  # mounted upside down


def _slow(frame: dict[str, Any]) -> dict[str, Any] | None:
    return frame if round(frame["t"] / 0.01) % 4 == 0 else None  # one frame in four: 25 Hz where 100 are declared


CASES = {
    "gyro_saturated": (
        _saturated,
        "imu_shank",
        "Left shank IMU: gyro saturated (reading at the sensor's full scale, 2000 deg/s); shank angle from the "
        "accelerometer alone",
    ),
    "missing": (_missing, "imu_shank", "Left shank IMU: no data for 0.3 s; shank angle held"),
    "accel_implausible": (
        _flipped,
        "imu_shank",
        "Left shank IMU: accelerometer upside down, an axis flipped or reading out of range; check the mounting; "
        "shank angle unreliable",
    ),
    "sample_rate": (
        _slow,
        "imu_foot,imu_shank,imu_thigh",
        "Left foot, shank and thigh IMUs: samples arrive every 40 ms, expected 10 ms; check the device's sample rate",
    ),
}


@functools.cache
def _walk() -> list[dict[str, Any]]:
    sensors, _, _ = sensor_trial([(1.0, 0.0, 8)], rate_hz=RATE)
    return [{"type": "frame", "t": f.t, **f.model_dump(include=set(IMU_CHANNELS))} for f in frames_from_table(sensors)]


@pytest.fixture
def fast_device(monkeypatch: pytest.MonkeyPatch) -> None:
    """The test sends its 100 Hz frames as fast as the socket takes them: the device's real token bucket, with a
    burst allowance of the whole test, takes them all."""
    monkeypatch.setattr(manager, "LiveDevice", functools.partial(LiveDevice, burst_s=3600.0))


@pytest.mark.usefixtures("fast_device")
@pytest.mark.parametrize("problem", list(CASES))
def test_a_faulty_imu_is_reported_once_the_torque_stays_bounded_and_its_recovery_is_reported(
    client: TestClient, problem: str
) -> None:
    inject, field, words = CASES[problem]
    r = client.post("/api/subjects", json={"code": "F01", "leg_length_m": 0.9, "mass_kg": 70.0, "side": "left"})
    source = {"kind": "device", "rate_hz": RATE, "channels": IMU_CHANNELS}
    body = {"subject_id": r.json()["id"], "source": source, "settings": {"max_torque_Nm": MAX_TORQUE}}
    r = client.post("/api/sessions", json=body)
    assert r.status_code == 201, r.text
    sid = int(r.json()["id"])
    runtime = client.app.state.ctx.manager.get(sid)  # type: ignore[attr-defined]
    assert {"imu_foot", "imu_shank", "imu_thigh", "phase_ekf"} <= set(runtime.estimator.stack.names)
    assert runtime.estimator.primary == "phase_ekf"  # the faulty sensor feeds the phase estimator
    torques: list[float] = []
    during: dict[str, Any] = {}
    with client.websocket_connect(device_path(client, sid)) as device:
        for frame in _walk():
            if FAULT[0] <= frame["t"] < FAULT[1]:
                faulty = inject(frame)
                if faulty is None:
                    continue
                frame = faulty
            elif frame["t"] >= FAULT[1] and not during:
                during = runtime.health().model_dump()  # at the fault's last sample
            device.send_text(json.dumps({**frame, "seq": len(torques)}))
            reply = json.loads(device.receive_text())
            assert reply["type"] == "torque", reply
            torques.append(reply["torque_Nm"])
        after = runtime.health().model_dump()
        state = client.get(f"/api/sessions/{sid}").json()["state"]
    # the torque: assistance given, never beyond the session's bound, finite, before, during and after the fault
    assert all(math.isfinite(v) and 0.0 <= v <= MAX_TORQUE for v in torques)
    assert max(torques) > 1.0
    # the session and its whole stack still run
    assert state == "running" and runtime.ended is None and after["failed_estimators"] == {}
    # data health: the problem while it lasts, then ok
    assert during["imu"] == "fault" and during["imu_note"].startswith(words.split(":")[0] + ":")
    assert after["imu"] == "ok" and after["imu_note"] == ""
    # the events: one when it started, in the clinician's words, one when it ended; nothing else about the IMUs
    events = client.get(f"/api/sessions/{sid}/events").json()
    imu = [e for e in events if e["field"] and set(e["field"].split(",")) <= FRONT_ENDS]
    assert [(e["field"], e["kind"], e["before"], e["after"]) for e in imu] == [
        (field, "system", "ok", problem),
        (field, "system", problem, "ok"),
    ]
    on, off = imu
    assert on["text"] == words and FAULT[0] < on["t"] < FAULT[1]
    assert off["text"].startswith(words.split(":")[0] + ": recovered (" + PROBLEMS[problem].short + " for ")
    assert FAULT[1] + 0.9 < off["t"] < FAULT[1] + 1.1
    assert client.post(f"/api/sessions/{sid}/stop").status_code == 200
