"""Adding an estimator is its two files, one registry line and its tests (docs/adding_an_estimator.md): a toy
estimator (:mod:`tests.sessions.toy_estimator`, one plotted output), registered for the test's time through
its line in ``DESCRIPTORS``, runs in a real session of the real app, is streamed to the browser, recorded in
the trial's MCAP file, re-run in review and described to the browser by the generated ``wire.js``."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from gaitscope.server.wire import render
from gaitscope.sessions import registry
from gaitscope.sessions.formats.mcap_io import read_messages
from tests.estimator_doubles import register
from tests.server.apps import session, wait_samples
from tests.sessions.toy_estimator import DESCRIPTOR, ToyCadence

TOY = DESCRIPTOR.name


@pytest.fixture
def toy(monkeypatch: pytest.MonkeyPatch) -> None:
    register(monkeypatch, DESCRIPTOR.built_by(lambda ctx: ToyCadence()))  # its line in the registry


def _cadences(values: list[float | None]) -> list[float]:
    return [v for v in values if v is not None and v > 0]


@pytest.mark.usefixtures("toy")
def test_a_registered_toy_runs_streams_records_and_re_runs(client: TestClient) -> None:
    assert TOY in registry.ESTIMATORS and TOY not in registry.OPT_IN
    s = session(client)  # a simulated walk at 1.2 m/s, 200 Hz: the default stack runs every estimator it can
    sid = s["id"]
    runtime = client.app.state.ctx.manager.get(sid)  # type: ignore[attr-defined]
    assert TOY in runtime.estimator.stack.names

    # the stream: its outputs in every batch, by name
    with client.websocket_connect(f"/ws/sessions/{sid}?max_rate_hz=0&batch_ms=20") as ws:
        assert json.loads(ws.receive_text())["type"] == "hello"
        streamed: list[float | None] = []
        while len(_cadences(streamed)) < 50:
            msg = json.loads(ws.receive_text())
            if msg["type"] == "states":
                assert not msg["estimators"][TOY]["failed"]
                streamed += msg["estimators"][TOY]["columns"]["cadence_spm"]
    assert all(40 < c < 80 for c in _cadences(streamed)[5:])  # about a stride a second at 1.2 m/s

    # the recording (a session records from its start): its own channel in the trial's MCAP file
    wait_samples(client, sid, 3.0)
    client.post(f"/api/sessions/{sid}/stop")
    [trial] = client.get(f"/api/trials?session_id={sid}").json()
    path = client.app.state.ctx.settings.data_dir / trial["path"]  # type: ignore[attr-defined]
    recorded = [m for _, _, m in read_messages(path, [f"/estimators/{TOY}"])]
    assert len(recorded) >= 600 and {m["name"] for m in recorded} == {TOY}
    assert all(m["values"].keys() == {"cadence_spm"} for m in recorded)
    assert all(40 < c < 80 for c in _cadences([m["values"]["cadence_spm"] for m in recorded])[5:])

    # a review re-run: the toy with a phase estimator (a stack needs one to drive the torque)
    r = client.post(f"/api/trials/{trial['id']}/rerun?max_points=20000", json={"estimators": ["tbe", TOY]})
    assert r.status_code == 200, r.text
    rerun = r.json()
    assert [k for k in rerun if "." in k] == ["tbe.phase", "tbe.phase_rate", f"{TOY}.cadence_spm"]
    assert all(40 < c < 80 for c in _cadences(rerun[f"{TOY}.cadence_spm"])[5:])
    choices = client.get(f"/api/trials/{trial['id']}/estimators").json()
    assert TOY in choices["default"]


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")
def test_the_generated_wire_file_describes_a_registered_toy(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    assert f"{TOY}:" not in render()
    register(monkeypatch, DESCRIPTOR.built_by(lambda ctx: ToyCadence()))
    module = tmp_path / "wire.js"
    module.write_text(render(), encoding="utf-8")
    script = f"import * as w from {json.dumps(module.as_uri())}; console.log(JSON.stringify(w.ESTIMATORS));"
    done = subprocess.run(["node", "--input-type=module", "-e", script], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    estimators = json.loads(done.stdout)
    assert list(estimators)[-1] == TOY  # last: it runs after every registered one
    assert estimators[TOY] == {
        "label": "Toy cadence",
        "outputs": {"cadence_spm": "1/min"},
        "quantities": {},
        "plots": [
            {"key": "toy_cadence", "title": "Toy: cadence", "y_label": "strides/min", "outputs": ["cadence_spm"]}
        ],
        "opt_in": False,
        "derives": False,
        "learned_model": None,
        "fingerprint": None,
    }
