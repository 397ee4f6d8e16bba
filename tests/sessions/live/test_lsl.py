"""Lab Streaming Layer on loopback: a stream as a session's source, and the gait state as an outlet.

Each test pushes a known signal from its own ``StreamOutlet`` (a unique name, so that tests running at the same
time on one machine never resolve each other's streams) and reads it back through gaitscope: the source's frames
(mapped channels, times from the LSL timestamps), and through the real app a session started from the stream,
whose gait-state outlet a ``StreamInlet`` here reads back. liblsl's default configuration finds streams on this
machine (multicast and broadcast on the loopback interface), so no configuration file is needed.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import json
import math
import threading
import time
import uuid
from collections.abc import Iterator
from types import SimpleNamespace

import pylsl
import pytest
from fastapi.testclient import TestClient
from pydantic import ValidationError

from gaitscope.sessions import schema
from gaitscope.sessions.live import lsl_outlet
from gaitscope.sessions.live.lsl_source import LslDevice, LslRefused, channel_map, open_stream, rig_of
from tests.waiting import wait_until

# Before liblsl's first use in this process: streams are looked for on this machine only (the tests' traffic
# stays off the network), and liblsl logs errors only (not its start-up notes).
pylsl.set_config_content("[multicast]\nResolveScope = machine\n\n[log]\nlevel = -2\n")

RATE = 100.0
LABELS = ("shank", "foot", "counter")


def shank(k: int) -> float:
    return 20.0 * math.sin(2 * math.pi * k / RATE)


def foot(k: int) -> float:
    return 10.0 * math.cos(2 * math.pi * k / RATE) - 5.0


class Sender:
    """An LSL outlet of three channels (labelled ``shank``, ``foot``, ``counter``) pushing sample ``k`` at LSL time
    ``start + k / RATE`` in real time from a thread, until :meth:`pause` or the end of its ``with``."""

    def __init__(self, name: str):
        info = pylsl.StreamInfo(name, "IMU", 3, RATE, pylsl.cf_double64, f"{name}-src")
        channels = info.desc().append_child("channels")
        for label in LABELS:
            channels.append_child("channel").append_child_value("label", label)
        self.name = name
        self.outlet = pylsl.StreamOutlet(info)
        self.start = pylsl.local_clock()
        self.k = 0
        self.paused = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self._stop.is_set():
            due = self.start + self.k / RATE
            wait = due - pylsl.local_clock()
            if wait > 0:
                time.sleep(min(0.005, wait))
                continue
            if not self.paused.is_set():
                self.outlet.push_sample([shank(self.k), foot(self.k), float(self.k)], due)
            self.k += 1

    def __enter__(self) -> Sender:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()


@pytest.fixture
def sender() -> Iterator[Sender]:
    with Sender(f"gs-test-{uuid.uuid4().hex[:12]}") as s:
        yield s


def _spec(name: str, **kw: object) -> schema.LslSource:
    fields: dict[str, object] = {
        "name": name,
        "type": "IMU",
        "mapping": {"0": "shank_angle_deg", "foot": "foot_angle_deg"},
    }
    return schema.LslSource.model_validate({**fields, **kw})


# --- mapping, rig, schema -------------------------------------------------------------------------


def test_a_mapping_takes_indices_and_labels_and_refuses_what_the_stream_lacks() -> None:
    labels = list(LABELS)
    assert channel_map({"2": "knee_angle_deg", "shank": "shank_angle_deg"}, 3, labels) == [
        (0, "shank_angle_deg"), (2, "knee_angle_deg")
    ]  # fmt: skip
    with pytest.raises(LslRefused, match="stream channel 3 mapped to knee_angle_deg, but the stream has 3 channels"):
        channel_map({"3": "knee_angle_deg"}, 3, labels)
    with pytest.raises(LslRefused, match=r"'thigh' mapped to thigh_angle_deg is not a label.*'shank', 'foot'"):
        channel_map({"thigh": "thigh_angle_deg"}, 3, labels)
    with pytest.raises(LslRefused, match="stream channel 0 is mapped twice"):
        channel_map({"0": "shank_angle_deg", "shank": "foot_angle_deg"}, 3, labels)


def test_the_source_spec_refuses_unknown_channels_and_a_stream_without_name_or_type() -> None:
    with pytest.raises(ValidationError, match="unknown channel shank_angle_rad"):
        schema.LslSource(name="x", mapping={"0": "shank_angle_rad"})
    with pytest.raises(ValidationError, match="mapped from more than one stream channel"):
        schema.LslSource(name="x", mapping={"0": "shank_angle_deg", "1": "shank_angle_deg"})
    with pytest.raises(ValidationError, match="needs the stream's name or type"):
        schema.LslSource(mapping={"0": "shank_angle_deg"})
    with pytest.raises(ValidationError):
        schema.LslSource(name="x' or name='y")  # no quotes: they would change the resolver's query


def test_a_rig_is_its_name_type_channel_count_and_source_id() -> None:
    rig = rig_of("Xsens", "IMU", 12, "xs-01")
    assert rig.startswith("lsl-") and len(rig) == 20 and rig == rig_of("Xsens", "IMU", 12, "xs-01")
    assert len({rig, rig_of("Xsens", "IMU", 13, "xs-01"), rig_of("Xsens", "EMG", 12, "xs-01")}) == 3


# --- the source -----------------------------------------------------------------------------------


def _frames(device: LslDevice, n: int) -> list[schema.SensorFrame]:
    async def take() -> list[schema.SensorFrame]:
        out: list[schema.SensorFrame] = []
        frames = device.frames()
        async with contextlib.aclosing(frames):
            async for f in frames:
                out.append(f)
                if len(out) == n:
                    break
        return out

    return asyncio.run(asyncio.wait_for(take(), 10.0))


def test_the_source_gives_the_mapped_channels_at_the_stream_s_times(sender: Sender) -> None:
    device = open_stream(_spec(sender.name, mapping={"0": "shank_angle_deg", "foot": "foot_angle_deg",
                                                     "counter": "knee_angle_deg"}))  # fmt: skip
    assert device.rate_hz == RATE and device.channels == {"shank_angle_deg", "foot_angle_deg", "knee_angle_deg"}
    assert device.rig == rig_of(sender.name, "IMU", 3, f"{sender.name}-src")
    frames = _frames(device, 60)
    k0 = int(frames[0].knee_angle_deg)
    for i, f in enumerate(frames):
        k = k0 + i  # every sample, in order
        assert f.seq == i and f.knee_angle_deg == k
        assert f.shank_angle_deg == pytest.approx(shank(k), abs=1e-9)
        assert f.foot_angle_deg == pytest.approx(foot(k), abs=1e-9)
        assert f.t == pytest.approx(i / RATE, abs=1e-4)  # LSL time from the first sample
        assert f.thigh_angle_deg is None and f.sent_ns is not None
    assert device.origin == pytest.approx(sender.start + k0 / RATE + device.correction, abs=1e-6)


def test_a_stream_that_is_not_there_is_refused_by_name_within_its_timeout() -> None:
    started = time.monotonic()
    with pytest.raises(
        LslRefused, match=r"LSL stream name 'gs-absent', type 'IMU' not found on the network within 0.3 s"
    ):
        open_stream(_spec("gs-absent", resolve_timeout_s=0.3))
    assert time.monotonic() - started < 2.0


def test_a_stream_without_a_mapping_needs_one_saved_for_its_rig(sender: Sender) -> None:
    with pytest.raises(LslRefused, match="has no channel mapping: none given and none saved for its rig"):
        open_stream(_spec(sender.name, mapping=None))
    saved = schema.SavedMapping(
        rig="r", kind="lsl", mapping=json.dumps({"1": "foot_angle_deg"}), actor="a", updated_utc=""
    )
    device = open_stream(_spec(sender.name, mapping=None), lambda rig: saved)
    assert device.channels == {"foot_angle_deg"}
    device.close()


def test_a_quiet_stream_is_noticed_and_its_return_too(sender: Sender) -> None:
    device = open_stream(_spec(sender.name, quiet_s=0.3))

    async def run() -> list[schema.SensorFrame]:
        out: list[schema.SensorFrame] = []
        frames = device.frames()
        async with contextlib.aclosing(frames):
            async for f in frames:
                out.append(f)
                if len(out) == 10:
                    sender.paused.set()
                    while not device.quiet:
                        await asyncio.sleep(0.02)
                    assert "went quiet (no sample for 0.3 s)" in device.notices[0]
                    sender.paused.clear()
                if len(out) > 10 and f.t - out[-2].t > 0.25:  # the first sample after the pause
                    break
        return out

    frames = asyncio.run(asyncio.wait_for(run(), 10.0))
    assert not device.quiet and "resumed after" in device.notices[-1]
    assert 0.3 <= frames[-1].t - frames[-2].t < 3.0  # the times keep the pause


def test_a_push_that_fails_is_counted_and_never_raised() -> None:
    class Broken:
        def push_sample(self, values: list[float], stamp: float) -> None:
            raise RuntimeError("liblsl said no")

    host = SimpleNamespace(source=SimpleNamespace(rate_hz=100.0), session=SimpleNamespace(id=1))
    outlet = lsl_outlet.GaitStateOutlet(host)
    outlet.outlet, outlet._clock = Broken(), pylsl.local_clock
    state = schema.GaitState(
        seq=0, t=0.0, phase=0.5, phase_rate=1.0, stride_length_m=None, incline_deg=None, torque_Nm=1.0,
        tbe_phase=None, heel_strike=False, backup_reset=False, foot_angle_deg=None, shank_angle_deg=None,
        thigh_angle_deg=None, foot_pred_deg=None, shank_pred_deg=None, recv_ns=time.time_ns(),
    )  # fmt: skip
    for _ in range(3):
        outlet.on_sample(state, [])
    assert (outlet.pushed, outlet.failed) == (0, 3)


# --- the real app ---------------------------------------------------------------------------------


def _outlet_id(client: TestClient, sid: int) -> str:
    """The source id of session ``sid``'s outlet: this test's own (another process's session ``sid`` is not)."""
    return lsl_outlet.source_id_of(sid, client.app.state.ctx.settings.data_dir)  # type: ignore[attr-defined]


def _subject(client: TestClient) -> int:
    r = client.post("/api/subjects", json={"code": "LSL01", "leg_length_m": 0.9, "mass_kg": 70.0})
    return int(r.json()["id"])


def test_a_session_runs_on_an_lsl_stream_and_publishes_its_gait_state(client: TestClient, sender: Sender) -> None:
    subject = _subject(client)
    source = _spec(sender.name).model_dump()
    r = client.post("/api/sessions", json={"subject_id": subject, "source": source, "settings": {"lsl_outlet": True}})
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    assert r.json()["state"] == "running"
    found = pylsl.resolve_bypred(f"source_id='{_outlet_id(client, sid)}'", 1, 5.0)
    assert found, "the session's gait-state outlet was not found"
    assert (found[0].name(), found[0].type()) == (f"gaitscope session {sid}", lsl_outlet.STREAM_TYPE)
    inlet = pylsl.StreamInlet(found[0])
    try:
        info = inlet.info(5.0)
        assert info.channel_count() == len(lsl_outlet.CHANNELS) and info.nominal_srate() == RATE
        labels = []
        channel = info.desc().child("channels").child("channel")
        while not channel.empty():
            labels.append(channel.child_value("label"))
            channel = channel.next_sibling("channel")
        assert labels == [name for name, _ in lsl_outlet.CHANNELS]
        inlet.open_stream(5.0)
        samples: list[list[float]] = []
        stamps: list[float] = []
        deadline = time.monotonic() + 10.0
        while len(samples) < 50 and time.monotonic() < deadline:
            chunk, ts = inlet.pull_chunk(timeout=0.5, min_samples=1)
            samples += chunk
            stamps += ts
    finally:
        inlet.close_stream()
    assert len(samples) >= 50
    shank_col = labels.index("shank_angle_deg")
    torque_col = labels.index("torque_Nm")
    for sample, stamp in zip(samples, stamps, strict=True):
        k = round((stamp - sender.start) * RATE)  # the gait state carries its sensor sample's LSL time
        assert stamp == pytest.approx(sender.start + k / RATE, abs=2e-3)
        assert sample[shank_col] == pytest.approx(shank(k), abs=1e-6)
        assert math.isfinite(sample[torque_col])
    # the mapping given is saved for the stream's rig: the next session of the rig needs none
    rig = rig_of(sender.name, "IMU", 3, f"{sender.name}-src")
    saved = {m["rig"]: m for m in client.get("/api/mappings").json()}
    assert saved[rig]["kind"] == "lsl" and json.loads(saved[rig]["mapping"]) == source["mapping"]
    assert client.post(f"/api/sessions/{sid}/stop").status_code == 200
    again = client.post("/api/sessions", json={"subject_id": subject, "source": {**source, "mapping": None}})
    assert again.status_code == 201 and again.json()["state"] == "running", again.text
    assert client.post(f"/api/sessions/{again.json()['id']}/stop").status_code == 200


def test_a_session_on_a_stream_that_is_not_there_is_refused_with_its_name(client: TestClient) -> None:
    subject = _subject(client)
    source = _spec("gs-nowhere", resolve_timeout_s=0.3).model_dump()
    r = client.post("/api/sessions", json={"subject_id": subject, "source": source})
    assert r.status_code == 409
    assert "LSL stream name 'gs-nowhere', type 'IMU' not found on the network within 0.3 s" in r.json()["detail"]
    (session,) = client.get("/api/sessions", params={"subject_id": subject}).json()
    assert session["state"] == "failed"
    events = client.get(f"/api/sessions/{session['id']}/events").json()
    assert any("gs-nowhere" in e["text"] for e in events)


def test_a_session_mapping_to_an_unknown_channel_is_refused(client: TestClient) -> None:
    subject = _subject(client)
    source = {"kind": "lsl", "name": "gs-any", "mapping": {"0": "shank_angle"}}
    r = client.post("/api/sessions", json={"subject_id": subject, "source": source})
    assert r.status_code == 422 and "unknown channel shank_angle" in r.text
    assert client.get("/api/sessions", params={"subject_id": subject}).json() == []


def test_a_session_whose_stream_lacks_a_mapped_label_is_refused(client: TestClient, sender: Sender) -> None:
    subject = _subject(client)
    source = _spec(sender.name, mapping={"thigh": "thigh_angle_deg"}).model_dump()
    r = client.post("/api/sessions", json={"subject_id": subject, "source": source})
    assert r.status_code == 409 and "'thigh' mapped to thigh_angle_deg is not a label" in r.json()["detail"]


def _texts(client: TestClient, sid: int) -> list[str]:
    return [e["text"] for e in client.get(f"/api/sessions/{sid}/events").json()]


def test_a_quiet_stream_holds_its_session_with_events(client: TestClient, sender: Sender) -> None:
    source = _spec(sender.name, quiet_s=0.3).model_dump()
    r = client.post("/api/sessions", json={"subject_id": _subject(client), "source": source})
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    sender.paused.set()
    wait_until(lambda: any("went quiet" in t for t in _texts(client, sid)), 10.0, "the quiet event")
    assert client.get(f"/api/sessions/{sid}").json()["state"] == "running"  # held, as a disconnected device
    sender.paused.clear()
    wait_until(lambda: any("resumed after" in t for t in _texts(client, sid)), 10.0, "the resumed event")
    assert client.post(f"/api/sessions/{sid}/stop").status_code == 200


def test_a_simulated_session_publishes_its_gait_state_at_each_frame_s_arrival(client: TestClient) -> None:
    source = {"kind": "simulated", "protocol": [{"speed_m_s": 1.2, "incline_deg": 0.0, "strides": 50}]}
    r = client.post(
        "/api/sessions", json={"subject_id": _subject(client), "source": source, "settings": {"lsl_outlet": True}}
    )
    sid = r.json()["id"]
    found = pylsl.resolve_bypred(f"source_id='{_outlet_id(client, sid)}'", 1, 5.0)
    assert found and found[0].type() == "GaitState" and found[0].nominal_srate() == 200.0
    inlet = pylsl.StreamInlet(found[0])
    try:
        inlet.open_stream(5.0)
        stamps: list[float] = []
        while len(stamps) < 40:
            _, ts = inlet.pull_chunk(timeout=1.0, min_samples=1)
            assert ts, "no gait state came"
            stamps += ts
            now = pylsl.local_clock()
            assert all(now - 1.0 < s <= now for s in ts)  # when the frame arrived, on this machine's LSL clock
    finally:
        inlet.close_stream()
    assert all(b > a for a, b in itertools.pairwise(stamps))
    assert client.post(f"/api/sessions/{sid}/stop").status_code == 200
