"""Seed 003's GP-EKF learning the wearer in a live session (issue #11, section 3), through the real app: a device
session whose stack runs ``gp_ekf`` streams seed 003's sinusoidal-speed walk (joint encoders and heel strikes,
200 Hz) over the real websocket. It retrains in the server's worker process while streaming, each install an
event with its training window and held-out RMSE, each version recorded with its arrays on ``/gp_models``; the
learning state serves the learned bands; freeze stops installs, a rollback reinstalls at the next heel strike,
both logged with the actor; a fit that raises, and a worker that dies, are events and the session goes on; and
a review re-run reproduces the live GP-EKF outputs exactly, installs included.

The device waits for each fit to come back before its next frame, so that every fit is offered at the same
sample whatever the machine's speed: the test is deterministic.
"""

from __future__ import annotations

import json
import math
import os
import signal
from concurrent.futures import wait
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from starlette.testclient import WebSocketTestSession

from gaitscope.estimators.gp import FitOptions
from gaitscope.estimators.gp_models import GPModelSet, TrainingWindow, fit_models
from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.sessions import schema
from gaitscope.sessions.estimation import FrameEstimator
from gaitscope.sessions.formats.mcap_io import read_events, read_messages
from gaitscope.sessions.gp_models import models_of, window_text
from gaitscope.sessions.live import gp_learning
from gaitscope.sessions.live.gp_learning import GPLearning, GPTrainer, Note
from gaitscope.sessions.live.runtime import SessionRuntime
from gaitscope.sessions.live.sources import frames_from_table
from gaitscope.sessions.schema import SensorFrame, SessionSettings
from gaitscope.sessions.synth.cohort import CohortSpec, make_subjects
from gaitscope.sessions.synth.speed_walks import SpeedProtocol, speed_walk
from tests.device_tokens import device_path

CHANNELS = ["hip_angle_deg", "knee_angle_deg", "ankle_angle_deg", "heel_strike"]
#: 25 s of walking (five stances a window: three or four windows), then standing
WALK = SpeedProtocol(walk_s=25.0, standing_s=2.0)
STACK = ["tbe", "gp_ekf"]


@pytest.fixture(scope="module")
def walk() -> tuple[list[dict[str, Any]], float, float]:
    """The walk's device frames (as JSON objects) and the subject's leg length and mass."""
    subject = make_subjects(CohortSpec())[0]
    table = speed_walk(subject, WALK)
    frames = [json.loads(f.model_dump_json(exclude_none=True)) for f in frames_from_table(table[["time_s", *CHANNELS]])]
    return frames, subject.leg_length_m, subject.mass_kg


def _session(client: TestClient, walk: tuple[list[dict[str, Any]], float, float], stack: list[str] = STACK) -> int:
    _, leg, mass = walk
    r = client.post("/api/subjects", json={"code": f"G{len(client.get('/api/subjects').json())}",
                                           "leg_length_m": leg, "mass_kg": mass})  # fmt: skip
    assert r.status_code == 201, r.text
    source = {"kind": "device", "rate_hz": 1000.0, "channels": CHANNELS}  # as fast as the socket takes them
    settings = {"estimators": stack, "primary": "gp_ekf" if "gp_ekf" in stack else "tbe"}
    r = client.post("/api/sessions", json={"subject_id": r.json()["id"], "source": source, "settings": settings})
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def _runtime(client: TestClient, sid: int) -> SessionRuntime:
    runtime = client.app.state.ctx.manager.get(sid)  # type: ignore[attr-defined]
    assert runtime is not None
    return runtime


def _send(client: TestClient, sid: int, device: WebSocketTestSession, frames: list[dict[str, Any]], t1: float) -> None:
    """Send the frames up to session time ``t1`` not sent yet, each after the last one's torque came back and
    the fit it started (if any) is done."""
    runtime = _runtime(client, sid)
    start = runtime.samples
    for frame in frames[start:]:
        if frame["t"] >= t1:
            break
        device.send_text(json.dumps({**frame, "type": "frame", "seq": runtime.samples}))
        assert json.loads(device.receive_text())["type"] == "torque"
        learning = runtime.gp_learning
        if learning is not None and learning.fitting is not None:
            done, _ = wait([learning.fitting], timeout=120)
            assert done, "a fit took over 2 minutes"


def _send_until_a_fit(client: TestClient, sid: int, device: WebSocketTestSession, frames: list[dict[str, Any]]) -> None:
    """Send the frames not sent yet, each after the last one's torque came back, up to the one whose window
    went to the worker (its fit left running)."""
    runtime = _runtime(client, sid)
    learning = runtime.gp_learning
    assert learning is not None
    for frame in frames[runtime.samples :]:
        device.send_text(json.dumps({**frame, "type": "frame", "seq": runtime.samples}))
        assert json.loads(device.receive_text())["type"] == "torque"
        if learning.fitting is not None:
            return
    raise AssertionError("no fit was submitted")


def _gp_events(client: TestClient, sid: int) -> list[dict[str, Any]]:
    return [e for e in client.get(f"/api/sessions/{sid}/events").json() if e["field"] == "gp_ekf"]


def _stop(client: TestClient, sid: int) -> Path:
    assert client.post(f"/api/sessions/{sid}/stop").status_code == 200
    (trial,) = client.get(f"/api/trials?session_id={sid}").json()
    return client.app.state.ctx.settings.data_dir / trial["path"]  # type: ignore[attr-defined, no-any-return]


def _rmse(record: dict[str, Any]) -> str:
    angles = [record["rmse"][f"{j} angle"] for j in schema.GP_JOINTS]
    return "held-out RMSE " + ", ".join(f"{j} {v:.1f}" for j, v in zip(schema.GP_JOINTS, angles, strict=True)) + " deg"


def _assert_rerun_reproduces(client: TestClient, path: Path) -> None:
    """A re-run of the trial (as recorded) gives the live GP-EKF's outputs, every one at every sample, and
    the live torque."""
    (trial,) = [t for t in client.get("/api/trials").json() if t["path"] == str(path.relative_to(path.parents[1]))]
    r = client.post(f"/api/trials/{trial['id']}/rerun?max_points=20000", json={})
    assert r.status_code == 200, r.text
    rerun = r.json()
    live = [m["values"] for _, _, m in read_messages(path, ["/estimators/gp_ekf"])]
    assert len(rerun["t"]) == len(live)
    for output in live[0]:
        np.testing.assert_array_equal(np.array(rerun[f"gp_ekf.{output}"]), [v[output] for v in live], err_msg=output)
    torque = [m["torque_Nm"] for _, _, m in read_messages(path, ["/gait_state"])]
    np.testing.assert_array_equal(rerun["torque_Nm"], torque)


# --- retraining while streaming ------------------------------------------------------------------------
def test_a_gp_ekf_session_retrains_logs_records_serves_its_bands_and_a_rerun_reproduces_it(
    client: TestClient, walk: tuple[list[dict[str, Any]], float, float]
) -> None:
    frames = walk[0]
    sid = _session(client, walk)
    state = client.get(f"/api/sessions/{sid}/gp-learning").json()
    assert (state["version"], state["waiting"], state["frozen"], state["pending"]) == (0, None, False, None)
    assert [v["version"] for v in state["versions"]] == [0] and state["versions"][0]["population"]
    with client.websocket_connect(device_path(client, sid)) as device:
        _send(client, sid, device, frames, math.inf)
        state = client.get(f"/api/sessions/{sid}/gp-learning").json()
        requested = client.get(f"/api/sessions/{sid}/gp-learning?version=1").json()["requested"]
        for bad in ("9", "-1", "one"):
            r = client.get(f"/api/sessions/{sid}/gp-learning?version={bad}")
            assert r.status_code == 422, (bad, r.text)
        assert (
            "GP model v9 is not kept (kept: v0, v1, v2, v3)"
            in client.get(f"/api/sessions/{sid}/gp-learning?version=9").json()["detail"]
        )
    path = _stop(client, sid)  # the stop waits for the events the sample path stored without waiting
    events = _gp_events(client, sid)

    records = [m for _, _, m in read_messages(path, ["/gp_models"])]
    trained = {m["version"]: m for m in records if m["what"] == "trained"}
    installed = [m for m in records if m["what"] == "installed"]
    # three windows of five stances in 25 s, each fitted in the worker, accepted and installed at a heel strike
    assert sorted(trained) == [1, 2, 3] and [m["version"] for m in installed] == [1, 2, 3]
    assert trained[1]["steps"] == [1, 5] and trained[2]["steps"] == [6, 10] and trained[3]["steps"] == [11, 15]
    assert all(0 < m["fit_s"] < 30 and m["reason"] == "" for m in trained.values())
    # each install is one event, at its heel strike, in plain words with its window and fit quality
    assert [e["text"] for e in events] == [
        f"{window_text(m['version'], tuple(trained[m['version']]['steps']), tuple(trained[m['version']]['span_s']))}, "
        f"{_rmse(trained[m['version']])}: installed at {m['t']:.2f} s"
        for m in installed
    ]
    assert events[0]["text"].startswith("GP model v1 trained on steps 1-5 (0.0-5.4 s), held-out RMSE hip ")
    assert [(e["t"], e["kind"], e["before"], e["after"], e["actor"]) for e in events] == [
        (m["t"], "system", float(m["version"] - 1), float(m["version"]), "system") for m in installed
    ]
    assert [e["text"] for e in read_events(path) if e.get("field") == "gp_ekf"] == [e["text"] for e in events]
    # the live outputs: the model version steps at the heel strikes where each one was installed
    live = [m["values"] for _, _, m in read_messages(path, ["/estimators/gp_ekf"])]
    t = np.array([m["t"] for _, _, m in read_messages(path, ["/estimators/gp_ekf"])])
    version = np.array([v["model_version"] for v in live])
    changes = np.flatnonzero(np.diff(version)) + 1
    assert [(t[k], version[k]) for k in changes] == [(m["t"], m["version"]) for m in installed]
    assert all(live[k]["heel_strike"] == 1.0 for k in changes)
    # the recorded arrays are the model: its held-out RMSE as recorded, its mean as the state's band
    models = {v: models_of({k: schema.GPArray(**a) for k, a in m["arrays"].items()}) for v, m in trained.items()}
    for v, m in trained.items():
        assert [m["rmse"][c] for c in ("hip angle", "knee angle", "ankle angle")] == models[v].rmse[:3].tolist()

    assert (state["version"], state["waiting"], state["frozen"], state["pending"]) == (3, None, False, None)
    assert [(v["version"], v["population"], v["installed_t"]) for v in state["versions"]] == [
        (0, True, []),
        *((m["version"], False, [m["t"]]) for m in installed),
    ]
    assert state["versions"][3]["steps"] == [11, 15] and state["versions"][3]["span_s"] == trained[3]["span_s"]
    assert state["versions"][3]["rmse_deg"]["knee"] == trained[3]["rmse"]["knee angle"]
    phase = np.array(state["phase"])
    assert phase.shape == (51,) and phase[0] == 0.0 and phase[-1] == 1.0
    for band, v in ((state["current"], 3), (requested, 1)):
        assert band["version"] == v
        for j, gp in zip(schema.GP_JOINTS, models[v].angle, strict=True):
            mean, lo, hi = (np.array(band[k][j]) for k in ("mean_deg", "lower_deg", "upper_deg"))
            np.testing.assert_allclose(mean, gp.mean(phase), rtol=1e-12)
            np.testing.assert_allclose(hi - mean, 2 * np.sqrt(gp.variance_at(phase)), rtol=1e-9)
            np.testing.assert_allclose(mean - lo, hi - mean, rtol=1e-9)
    knee = np.array(state["current"]["mean_deg"]["knee"])
    assert 10 < knee.max() - knee.min() < 80  # stance knee flexion: loading response, then push-off

    _assert_rerun_reproduces(client, path)


def test_a_later_trial_records_the_versions_kept_from_before_it_and_its_rerun_catches_up_at_a_heel_strike(
    client: TestClient, walk: tuple[list[dict[str, Any]], float, float]
) -> None:
    """A trial started while v1 runs holds v1 (``kept``, ``current``): its re-run installs it at its first heel
    strike and v2 where it was installed live; from its second stance on (the filter times a stance by the one
    before) it gives what ran."""
    frames = walk[0]
    sid = _session(client, walk)
    with client.websocket_connect(device_path(client, sid)) as device:
        _send(client, sid, device, frames, 7.0)
        for action in ("stop", "start"):
            assert client.post(f"/api/sessions/{sid}/recording", json={"action": action}).status_code == 200
        _send(client, sid, device, frames, 14.0)
    assert client.post(f"/api/sessions/{sid}/stop").status_code == 200
    _, second = sorted(client.get(f"/api/trials?session_id={sid}").json(), key=lambda t: t["id"])
    path = client.app.state.ctx.settings.data_dir / second["path"]  # type: ignore[attr-defined]
    records = [m for _, _, m in read_messages(path, ["/gp_models"])]
    assert [(m["what"], m["version"], m["current"]) for m in records] == [
        ("kept", 1, True), ("trained", 2, False), ("installed", 2, False)
    ]  # fmt: skip
    assert records[0]["arrays"] is not None and records[0]["steps"] == [1, 5]
    r = client.post(f"/api/trials/{second['id']}/rerun?max_points=20000", json={})
    assert r.status_code == 200, r.text
    rerun = r.json()
    live = [m["values"] for _, _, m in read_messages(path, ["/estimators/gp_ekf"])]
    strikes = [k for k, v in enumerate(live) if v["heel_strike"] == 1.0]
    assert rerun["gp_ekf.model_version"][strikes[0]] == 1.0 and rerun["gp_ekf.model_version"][-1] == 2.0
    for output in live[0]:
        np.testing.assert_array_equal(
            rerun[f"gp_ekf.{output}"][strikes[1] :], [v[output] for v in live[strikes[1] :]], err_msg=output
        )


# --- the clinician's controls ------------------------------------------------------------------------------
def test_freeze_stops_installs_a_rollback_reinstalls_and_both_are_logged_recorded_and_rerun(
    client: TestClient, walk: tuple[list[dict[str, Any]], float, float]
) -> None:
    frames = walk[0]
    sid = _session(client, walk)
    url = f"/api/sessions/{sid}/gp-learning"
    with client.websocket_connect(device_path(client, sid)) as device:
        _send(client, sid, device, frames, 6.0)
        assert client.get(url).json()["version"] == 1
        r = client.post(url, json={"action": "freeze", "actor": "local", "reason": "stumbling"})
        assert r.status_code == 200, r.text
        assert r.json()["frozen"] and r.json()["version"] == 1
        assert client.post(url, json={"action": "freeze", "actor": "dr b"}).status_code == 200  # no change, no event
        _send(client, sid, device, frames, 14.0)  # a window at step 10 (about 11.2 s): not taken, frozen
        state = client.get(url).json()
        assert (state["version"], state["pending"], state["waiting"]) == (1, None, None)
        for body, why in (
            ({"action": "rollback", "version": 2}, "GP model v2 is not kept; a rollback can reinstall v0, v1"),
            ({"action": "rollback", "version": 9}, "GP model v9 is not kept"),
        ):
            r = client.post(url, json=body)
            assert r.status_code == 422 and r.json()["detail"].startswith(why), r.text
        for body in ({"action": "rollback"}, {"action": "freeze", "version": 1}, {"action": "melt"},
                     {"action": "unfreeze", "extra": 1}, {"action": "rollback", "version": -1}, {}):  # fmt: skip
            assert client.post(url, json=body).status_code == 422, body
        r = client.post(url, json={"action": "rollback", "version": 0, "actor": "local"})
        assert r.status_code == 200, r.text
        assert (r.json()["version"], r.json()["waiting"], r.json()["rollback"]) == (1, 0, True)  # at a heel strike
        _send(client, sid, device, frames, 17.5)  # the slowest strides: 0.4 m/s at 15 s
        assert client.get(url).json()["version"] == 0  # installed while frozen: the clinician's choice
        r = client.post(url, json={"action": "unfreeze", "actor": "local"})
        assert r.status_code == 200 and not r.json()["frozen"]
        _send(client, sid, device, frames, math.inf)
        state = client.get(url).json()
    path = _stop(client, sid)  # the stop waits for the events the sample path stored without waiting
    events = _gp_events(client, sid)

    records = [m for _, _, m in read_messages(path, ["/gp_models"])]
    assert [(m["what"], m["version"], m["actor"]) for m in records] == [
        ("trained", 1, "system"), ("installed", 1, "system"), ("frozen", 1, "local"), ("rollback", 0, "local"),
        ("installed", 0, "system"), ("unfrozen", 0, "local"), ("trained", 3, "system"), ("installed", 3, "system"),
    ]  # fmt: skip
    assert records[2]["reason"] == "stumbling"
    back = records[4]["t"]
    assert [(e["kind"], e["actor"], e["before"], e["after"], e["text"]) for e in events[1:]] == [
        ("setting", "local", "learning", "frozen",
         "GP learning frozen by local: no retraining or installs until unfrozen, v1 stays (stumbling)"),
        ("setting", "local", 1.0, 0.0, "GP model rollback to v0 by local: installed at the next heel strike"),
        ("system", "system", 1.0, 0.0, f"GP model v0 reinstalled at {back:.2f} s (rollback by local)"),
        ("setting", "local", "frozen", "learning", "GP learning unfrozen by local: retraining resumes"),
        ("system", "system", 0.0, 3.0, f"{window_text(3, (11, 15), tuple(records[6]['span_s']))}, {_rmse(records[6])}"
                                       f": installed at {records[7]['t']:.2f} s"),
    ]  # fmt: skip
    assert events[3]["t"] == back and 14.0 <= back < 17.5
    assert [v["version"] for v in state["versions"]] == [0, 1, 3] and state["versions"][0]["installed_t"] == [back]
    version = [m["values"]["model_version"] for _, _, m in read_messages(path, ["/estimators/gp_ekf"])]
    assert sorted(set(version)) == [0.0, 1.0, 3.0]
    _assert_rerun_reproduces(client, path)

    for method, kw in (("get", {}), ("post", {"json": {"action": "freeze"}})):
        r = getattr(client, method)(url, **kw)
        assert r.status_code == 409 and r.json()["detail"].startswith(f"session {sid} is not running"), r.text
        assert getattr(client, method)("/api/sessions/999/gp-learning", **kw).status_code == 404


def test_a_session_without_the_gp_ekf_has_no_learning(
    client: TestClient, walk: tuple[list[dict[str, Any]], float, float]
) -> None:
    sid = _session(client, walk, ["tbe"])
    for r in (client.get(f"/api/sessions/{sid}/gp-learning"),
              client.post(f"/api/sessions/{sid}/gp-learning", json={"action": "freeze"})):  # fmt: skip
        assert (
            r.status_code == 409
            and r.json()["detail"] == f"session {sid} runs no GP-EKF: gp_ekf is not in its stack (tbe)"
        )
    path = _stop(client, sid)
    assert list(read_messages(path, ["/gp_models"])) == []


def test_a_fit_back_after_a_freeze_is_refused_and_said_so(
    small_model: TrainedModel, walk: tuple[list[dict[str, Any]], float, float]
) -> None:
    """Without the app: a stack's GP-EKF learning, its fits in a worker thread (the trainer's other kind)."""
    frames, leg, mass = walk
    settings = SessionSettings(estimators=["gp_ekf"], primary="gp_ekf")
    est = FrameEstimator(small_model, leg, mass, settings, 0.005, soft_start=False)
    trainer = GPTrainer("thread")
    learning = GPLearning.of(est.stack, trainer)
    assert learning is not None
    notes: list[Note] = []
    try:
        for k, frame in enumerate(frames):
            t = est.step(SensorFrame.model_validate({**frame, "seq": k}), 0).t
            notes += learning.poll(t)
            if learning.fitting is not None:  # the first window went to the worker: freeze before it is back
                freeze = schema.GPLearningControl(action="freeze", actor="dr a")
                note = learning.plan(freeze, t)
                assert note is not None and note.text.startswith("GP learning frozen by dr a")
                learning.apply(freeze)
                wait([learning.fitting])
                notes += learning.poll(t)
                break
    finally:
        trainer.shutdown()
    (refused,) = notes
    assert refused.record.what == "refused" and refused.record.version == 1 and refused.record.arrays is not None
    assert refused.text.startswith("GP model v1 trained on steps 1-5 (0.0-5.4 s), held-out RMSE hip ")
    assert refused.text.endswith(": kept v0 (learning is frozen)") and learning.version == 0
    state = learning.state(1)
    assert state.frozen and state.pending is None and state.last == refused.text


# --- failures --------------------------------------------------------------------------------------------
def _fails_first(window: TrainingWindow, options: FitOptions) -> tuple[GPModelSet, float, float]:
    """A fit that raises on the first window (runs in the worker process, which imports this module)."""
    if window.index == 1:
        raise RuntimeError("the fit blew up")
    return fit_models(window, options), 0.5, 0.5


def test_a_fit_that_raises_is_an_event_and_the_session_learns_on(
    client: TestClient, walk: tuple[list[dict[str, Any]], float, float], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(gp_learning, "fit_window", _fails_first)
    frames = walk[0]
    sid = _session(client, walk)
    with client.websocket_connect(device_path(client, sid)) as device:
        _send(client, sid, device, frames, 12.0)
        state = client.get(f"/api/sessions/{sid}/gp-learning").json()
    assert client.get(f"/api/sessions/{sid}").json()["state"] == "running"
    path = _stop(client, sid)  # the stop waits for the events the sample path stored without waiting
    events = _gp_events(client, sid)
    failed, trained, installed = [m for _, _, m in read_messages(path, ["/gp_models"])]
    assert (failed["what"], failed["version"], failed["steps"], failed["reason"]) == (
        "failed",
        1,
        [1, 5],
        "RuntimeError: the fit blew up",
    )
    assert (trained["what"], trained["version"], installed["what"], installed["version"]) == (
        "trained",
        2,
        "installed",
        2,
    )
    assert [e["text"] for e in events] == [
        "GP model v1 training on steps 1-5 (0.0-5.4 s) failed (RuntimeError: the fit blew up); kept v0",
        f"{window_text(2, (6, 10), tuple(trained['span_s']))}, {_rmse(trained)}: installed at {installed['t']:.2f} s",
    ]
    assert events[0]["t"] == failed["t"] and state["version"] == 2 and state["last"] == events[1]["text"]


def test_a_worker_that_dies_is_an_event_and_the_next_fit_gets_a_new_one(
    client: TestClient, walk: tuple[list[dict[str, Any]], float, float]
) -> None:
    frames = walk[0]
    sid = _session(client, walk)
    runtime = _runtime(client, sid)
    learning = runtime.gp_learning
    assert learning is not None
    with client.websocket_connect(device_path(client, sid)) as device:
        _send_until_a_fit(client, sid, device, frames)
        pool = learning.trainer._pool  # the worker process of the server's ProcessPoolExecutor
        (pid,) = pool._processes  # type: ignore[union-attr]
        os.kill(pid, signal.SIGKILL)
        _send(client, sid, device, frames, 12.0)
    path = _stop(client, sid)  # the stop waits for the events the sample path stored without waiting
    events = _gp_events(client, sid)
    assert events[0]["text"] == (
        "GP model v1 training on steps 1-5 (0.0-5.4 s) failed (its worker process stopped unexpectedly); kept v0"
    )
    assert events[1]["text"].startswith("GP model v2 trained on steps 6-10") and events[1]["after"] == 2.0
    assert [m["what"] for _, _, m in read_messages(path, ["/gp_models"])] == ["failed", "trained", "installed"]


def test_a_session_stopped_during_a_fit_stops_cleanly_and_the_worker_serves_the_next(
    client: TestClient, walk: tuple[list[dict[str, Any]], float, float]
) -> None:
    frames = walk[0]
    sid = _session(client, walk)
    runtime = _runtime(client, sid)
    learning = runtime.gp_learning
    assert learning is not None
    with client.websocket_connect(device_path(client, sid)) as device:
        _send_until_a_fit(client, sid, device, frames)
        fit = learning.fitting
    path = _stop(client, sid)  # the device gone, the fit under way (GPy's import alone takes a second)
    assert fit is not None and learning.fitting is None
    assert list(read_messages(path, ["/gp_models"])) == [] and _gp_events(client, sid) == []
    wait([fit], timeout=120)  # the worker finishes it, unheard (one fit at a time: the next waits for it)
    sid2 = _session(client, walk)  # the same worker fits the next session's windows
    with client.websocket_connect(device_path(client, sid2)) as device:
        _send(client, sid2, device, frames, 6.0)
    assert client.get(f"/api/sessions/{sid2}/gp-learning").json()["version"] == 1
    _stop(client, sid2)


def test_a_window_waiting_for_the_shared_worker_is_shown_until_it_goes(
    client: TestClient, walk: tuple[list[dict[str, Any]], float, float], monkeypatch: pytest.MonkeyPatch
) -> None:
    frames = walk[0]
    sid = _session(client, walk)
    learning = _runtime(client, sid).gp_learning
    assert learning is not None
    monkeypatch.setattr(learning.trainer, "may_submit", lambda session: False)  # the budget spent elsewhere
    with client.websocket_connect(device_path(client, sid)) as device:
        _send(client, sid, device, frames, 7.0)  # past the first window (5 stances)
        state = client.get(f"/api/sessions/{sid}/gp-learning").json()
        assert state["pending"] is None and state["queued_s"] is not None and state["queued_s"] >= 0.0
        assert learning.estimator.filter.window_ready  # kept, not dropped
        monkeypatch.undo()  # the worker is free: the window goes at the next sample
        _send_until_a_fit(client, sid, device, frames)
        state = client.get(f"/api/sessions/{sid}/gp-learning").json()
        assert state["queued_s"] is None and state["pending"]["steps"] == [1, 5]
    _stop(client, sid)
