"""Review shows what ran: a default re-run of a trial reproduces its recorded gait states, setting
changes included; a what-if holds other settings over the whole trial; bad time bounds are 422.

Recordings are made by a real :class:`~gaitscope.sessions.live.runtime.SessionRuntime` (driven frame by frame, or live
in the app) and read back through the real API on a temporary data folder.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from mcap.reader import make_reader

from gaitscope.sessions import registry, schema
from gaitscope.sessions.estimation import DEFAULT_PERIOD, estimate
from gaitscope.sessions.formats.mcap_io import SERIES_COLUMNS, read_messages
from gaitscope.sessions.formats.recording import METADATA_NAME, SAMPLE_PERIOD_KEY, Recorder
from gaitscope.sessions.live.runtime import SessionRuntime
from gaitscope.sessions.live.sources import LiveDevice, frames_from_table
from gaitscope.sessions.synth.trials import replay_columns, sensor_trial
from tests.uploads import upload
from tests.waiting import wait_until

RATE_HZ = 100.0  # the device's rate; the live estimator, not told it, runs with DEFAULT_PERIOD
ALL = 20000  # max_points above every trial's length: no decimation
#: (frame index before which the change is made, change); steps within SETTING_LIMITS' rates.
CHANGES = (
    (550, schema.SettingsChange(torque_gain=1.5, reason="more push-off", confirm=True)),
    (800, schema.SettingsChange(max_torque_Nm=20.0)),
    (950, schema.SettingsChange(measurement_noise_scale=3.0)),
)
#: Columns a re-run cannot reproduce: the server's wall clock at arrival (0 in a re-run).
NOT_ESTIMATED = {"recv_ns"}


def _subject(client: TestClient) -> int:
    r = client.post("/api/subjects", json={"code": "P01", "leg_length_m": 0.9, "mass_kg": 70.0})
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def _driven_trial(client: TestClient) -> tuple[int, list[float]]:
    """A device session driven frame by frame through the real runtime, with :data:`CHANGES`; returns
    the trial id and the session times of the changes (the last sample before each)."""
    ctx = client.app.state.ctx  # type: ignore[attr-defined]
    sid = _subject(client)
    r = client.post("/api/sessions", json={"subject_id": sid, "source": {"kind": "device"}, "start": False})
    assert r.status_code == 201, r.text
    session = ctx.store.get_session(r.json()["id"])
    model, _ = ctx.models.get(session.settings.model)
    runtime = SessionRuntime(session, ctx.store.get_subject(sid), model, LiveDevice(), ctx.store, ctx.settings.data_dir)
    trial = runtime.start_recording("walk")
    sensors, _, _ = sensor_trial([(1.2, 0.0, 12)], rate_hz=RATE_HZ)
    changes = dict(CHANGES)
    times = []
    for i, frame in enumerate(frames_from_table(sensors)):
        if i in changes:
            runtime.change_settings(changes[i])
            times.append(runtime.last_t)
        runtime.process(frame, time.time_ns())
    runtime.stop_recording()
    return trial.id, times


def _differences(a: dict[str, list[Any]], b: dict[str, list[Any]]) -> dict[str, float]:
    """Largest difference per column (inf where a value is missing or of another kind)."""
    assert len(a["t"]) == len(b["t"]) > 0
    out = {}
    for c in SERIES_COLUMNS:
        if c in NOT_ESTIMATED:
            continue
        worst = 0.0
        for x, y in zip(a[c], b[c], strict=True):
            if isinstance(x, float) and isinstance(y, float):
                worst = max(worst, abs(x - y))
            elif x != y:
                worst = math.inf
        out[c] = worst
    return out


def _reproduced(a: dict[str, list[Any]], b: dict[str, list[Any]]) -> bool:
    return all(d <= 1e-9 for d in _differences(a, b).values())


def _rerun(client: TestClient, tid: int, body: dict[str, Any] | None = None, query: str = "") -> dict[str, list[Any]]:
    r = client.post(f"/api/trials/{tid}/rerun?max_points={ALL}{query}", json=body)
    assert r.status_code == 200, r.text
    return r.json()


def test_default_rerun_reproduces_what_ran_across_setting_changes(client: TestClient) -> None:
    tid, times = _driven_trial(client)
    recorded = client.get(f"/api/trials/{tid}/series?max_points={ALL}").json()
    assert len(recorded["t"]) > 1000
    for body in (None, {}, {"settings": None}):  # no body, empty body, explicit null: all "as recorded"
        again = _rerun(client, tid, body)
        assert _reproduced(again, recorded), _differences(again, recorded)
    # A window is the same states (the estimator still starts at the first frame).
    t0, t1 = times[0] - 0.5, times[-1] + 0.5
    window = client.get(f"/api/trials/{tid}/series?t0={t0}&t1={t1}&max_points={ALL}").json()
    assert _reproduced(_rerun(client, tid, query=f"&t0={t0}&t1={t1}"), window)
    # The changes took effect live: the gain raised the peak torque, the bound then capped it.
    before = [q for t, q in zip(recorded["t"], recorded["torque_Nm"], strict=True) if 2.0 < t <= times[0]]
    between = [q for t, q in zip(recorded["t"], recorded["torque_Nm"], strict=True) if times[0] < t <= times[1]]
    after = [q for t, q in zip(recorded["t"], recorded["torque_Nm"], strict=True) if t > times[1]]
    assert max(between) > 1.2 * max(before) and max(after) <= 20.0 + 1e-9 < max(between)


def test_the_recording_holds_the_live_period_and_the_setting_timeline(client: TestClient) -> None:
    tid, times = _driven_trial(client)
    path = client.app.state.ctx.settings.data_dir / client.get(f"/api/trials/{tid}").json()["path"]  # type: ignore[attr-defined]
    with path.open("rb") as f:
        [meta] = [m for m in make_reader(f).iter_metadata() if m.name == METADATA_NAME]
    # Not 1 / 100 Hz: the live estimator was built before the device's rate was known.
    assert float(meta.metadata[SAMPLE_PERIOD_KEY]) == DEFAULT_PERIOD
    r = client.get(f"/api/trials/{tid}/settings")
    assert r.status_code == 200 and r.json() == schema.SessionSettings().model_dump()
    events = [e for e in client.get(f"/api/trials/{tid}/events").json() if e["kind"] == "setting"]
    assert [(e["t"], e["field"], e["before"], e["after"]) for e in events] == [
        (times[0], "torque_gain", 1.0, 1.5),
        (times[1], "max_torque_Nm", 30.0, 20.0),
        (times[2], "measurement_noise_scale", 1.0, 3.0),
    ]
    assert "more push-off" in events[0]["text"]


def test_what_if_holds_its_settings_over_the_whole_trial(client: TestClient) -> None:
    tid, times = _driven_trial(client)
    recorded = client.get(f"/api/trials/{tid}/series?max_points={ALL}").json()
    n_before = sum(1 for t in recorded["t"] if t <= times[0])

    def head(s: dict[str, list[Any]], n: int) -> dict[str, list[Any]]:
        return {c: v[:n] for c, v in s.items()}

    # The settings the trial began with: what ran up to the first change, then no longer.
    initial = _rerun(client, tid, {"settings": schema.SessionSettings().model_dump()})
    assert _reproduced(head(initial, n_before), head(recorded, n_before))
    assert not _reproduced(head(initial, n_before + 200), head(recorded, n_before + 200))
    # The session's final settings (what the UI used to send as the "baseline"): wrong from the start.
    final = client.get(f"/api/trials/{tid}").json()
    final_settings = client.get(f"/api/sessions/{final['session_id']}").json()["settings"]
    assert final_settings["torque_gain"] == 1.5
    what_if = _rerun(client, tid, {"settings": final_settings})
    early = [i for i, t in enumerate(recorded["t"]) if 3.0 < t <= times[0]]
    assert max(what_if["torque_Nm"][i] for i in early) > 1.2 * max(recorded["torque_Nm"][i] for i in early)
    assert what_if["t"] == recorded["t"]  # on the recording's times, to overlay it
    r = client.post(f"/api/trials/{tid}/rerun", json={"settings": {"model": "nope"}})
    assert r.status_code == 422 and r.json()["detail"] == "model 'nope' does not exist"


def test_live_session_rerun_reproduces_a_change_made_over_the_api(client: TestClient) -> None:
    source = {"kind": "simulated", "protocol": [{"speed_m_s": 1.2, "incline_deg": 0.0, "strides": 200}]}
    r = client.post("/api/sessions", json={"subject_id": _subject(client), "source": source})
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    runtime = client.app.state.ctx.manager.get(sid)  # type: ignore[attr-defined]

    def wait_samples(n: int) -> None:
        wait_until(lambda: runtime.samples >= n, 15.0, f"{n} samples")

    wait_samples(250)
    # The filter's tuning acts at once (a gain change would hide under the soft start's ramp).
    r = client.patch(f"/api/sessions/{sid}/settings", json={"measurement_noise_scale": 3.0})
    assert r.status_code == 200, r.text
    wait_samples(runtime.samples + 250)
    client.post(f"/api/sessions/{sid}/stop")
    [trial] = client.get(f"/api/trials?session_id={sid}").json()
    [change] = [e for e in client.get(f"/api/trials/{trial['id']}/events").json() if e["kind"] == "setting"]
    recorded = client.get(f"/api/trials/{trial['id']}/series?max_points={ALL}").json()
    again = _rerun(client, trial["id"])
    assert _reproduced(again, recorded), _differences(again, recorded)
    n = sum(1 for t in recorded["t"] if t <= change["t"])
    what_if = _rerun(client, trial["id"], {"settings": {}})  # the defaults it began with, never changed
    assert _reproduced({c: v[:n] for c, v in what_if.items()}, {c: v[:n] for c, v in recorded.items()})
    assert _differences(what_if, recorded)["stride_length_m"] > 1e-6


def test_default_rerun_reproduces_an_imported_log_whose_clock_does_not_start_at_0(
    client: TestClient, tmp_path: Path
) -> None:
    sensors, _, _ = sensor_trial([(1.0, 0.0, 8)], rate_hz=RATE_HZ)
    table = replay_columns(sensors)
    table["time_s"] += 3.25  # the device's clock; the review's session time starts at 0
    path = tmp_path / "walk.csv"
    table.to_csv(path, index=False, float_format="%.6f")
    trial = upload(client, path, _subject(client))
    recorded = client.get(f"/api/trials/{trial['id']}/series?max_points={ALL}").json()
    assert recorded["t"][0] == 0.0
    again = _rerun(client, trial["id"])
    assert _reproduced(again, recorded), _differences(again, recorded)


def test_a_trial_without_recorded_settings_has_no_as_recorded_rerun(client: TestClient, tmp_path: Path) -> None:
    path = tmp_path / "other_tool.mcap"
    sensors, _, _ = sensor_trial([(1.0, 0.0, 3)], rate_hz=RATE_HZ)
    frames = frames_from_table(sensors)
    model, _ = client.app.state.ctx.models.get("default")  # type: ignore[attr-defined]
    states = estimate(frames, model, 0.9, 70.0, schema.SessionSettings())
    with Recorder(path, 1_700_000_000_000_000_000, {"source": "other tool"}) as rec:
        for f, state in zip(frames, states, strict=True):  # from some other tool: no /settings
            rec.write("/sensor", f.t, f)
            rec.write("/gait_state", f.t, state)
    trial = upload(client, path, _subject(client))
    for r in (client.post(f"/api/trials/{trial['id']}/rerun"), client.get(f"/api/trials/{trial['id']}/settings")):
        assert r.status_code == 422 and "not recorded" in r.json()["detail"], r.text
    what_if = _rerun(client, trial["id"], {"settings": {"torque_gain": 1.0}})
    assert what_if["t"] == pytest.approx([f.t for f in frames]) and max(what_if["torque_Nm"]) > 5.0


def test_bounds_that_are_not_finite_times_are_422(client: TestClient) -> None:
    tid, _ = _driven_trial(client)
    for bound in ("t0=nan", "t1=inf", "t0=-inf", "t0=1e400", "t0=1&t1=NaN", "t0=1e300"):
        for r in (
            client.get(f"/api/trials/{tid}/series?{bound}"),
            client.post(f"/api/trials/{tid}/rerun?{bound}"),
            client.post(f"/api/trials/{tid}/rerun?{bound}", json={"settings": {"torque_gain": 2.0}}),
        ):
            assert r.status_code == 422, (bound, r.text)
            [error] = r.json()["detail"]
            assert error["loc"] in (["query", "t0"], ["query", "t1"])
            assert error["msg"] in ("Input should be a finite number", f"Input should be less than or equal to {10**9}")


def test_default_rerun_reproduces_every_estimators_recorded_outputs(client: TestClient) -> None:
    """Each estimator of the stack is recorded on ``/estimators/<name>``; the default re-run gives them
    back exactly (``<name>.<output>`` columns), and any subset can be re-run and overlaid."""
    tid, _ = _driven_trial(client)
    path = client.app.state.ctx.settings.data_dir / client.get(f"/api/trials/{tid}").json()["path"]  # type: ignore[attr-defined]
    again = _rerun(client, tid)
    stack = ("hs_detector", "phase_ekf", "tbe")  # the default stack (hs_backup is opt-in)
    for name in stack:
        recorded = [m for _, _, m in read_messages(path, [f"/estimators/{name}"])]
        assert len(recorded) == len(again["t"]) > 1000
        for output in recorded[0]["values"]:
            assert again[f"{name}.{output}"] == [m["values"][output] for m in recorded], (name, output)
    assert again["tbe_phase"] == again["tbe.phase"] and again["phase"] == again["phase_ekf.phase"]
    # A subset: the timing-based estimate alone drives the torque of this re-run.
    tbe = _rerun(client, tid, {"estimators": ["tbe"]})
    assert tbe["phase"] == tbe["tbe.phase"] and not any(k.startswith("phase_ekf.") for k in tbe)
    assert tbe["t"] == again["t"] and max(tbe["torque_Nm"]) > 5.0
    r = client.post(f"/api/trials/{tid}/rerun", json={"estimators": ["nope"]})
    assert r.status_code == 422 and "unknown estimator nope" in r.json()["detail"]


def test_the_estimators_a_rerun_can_run_are_the_recorded_stack_and_those_the_channels_feed(
    client: TestClient,
) -> None:
    """What the review's picker offers (``GET /api/trials/{id}/estimators``); the default re-run runs
    ``default``, and a subset of ``runnable`` runs exactly that subset."""
    tid, _ = _driven_trial(client)
    r = client.get(f"/api/trials/{tid}/estimators")
    assert r.status_code == 200, r.text
    # a device that declared no channels runs every estimator but the opt-in ones (and the personalized
    # filter, which needs the subject's fingerprint); its frames feed all of them
    every = [n for n in registry.ESTIMATORS if n != "fp_ls"]
    ran = [n for n in every if n not in registry.OPT_IN]
    assert r.json() == {
        "recorded": ran,
        "default": ran,
        "runnable": every,  # the opt-in backup too
        "derived": {},
        "refused": {"fp_ls": "needs the subject's calibrated gait fingerprint"},
    }
    ran = _rerun(client, tid, {"estimators": ["phase_ekf", "hs_backup"]})
    assert {k.split(".")[0] for k in ran if "." in k} == {"phase_ekf", "hs_backup"}
    assert client.get("/api/trials/999/estimators").status_code == 404


def test_a_subset_without_the_estimator_that_derives_a_channel_is_refused(client: TestClient, tmp_path: Path) -> None:
    """A log without heel strikes: the detector (or the phase EKF) derives them for the timing-based
    estimate, so the picker is told, and the timing-based estimate alone is refused with the reason."""
    path = tmp_path / "no_heel_strikes.mcap"
    sensors, _, _ = sensor_trial([(1.0, 0.0, 3)], rate_hz=RATE_HZ)
    frames = [f.model_copy(update={"heel_strike": None}) for f in frames_from_table(sensors)]
    model, _ = client.app.state.ctx.models.get("default")  # type: ignore[attr-defined]
    states = estimate(frames, model, 0.9, 70.0, schema.SessionSettings())
    with Recorder(path, 1_700_000_000_000_000_000, {"source": "other tool"}) as rec:
        for f, state in zip(frames, states, strict=True):
            rec.write("/sensor", f.t, f)
            rec.write("/gait_state", f.t, state)
    tid = upload(client, path, _subject(client))["id"]
    choices = client.get(f"/api/trials/{tid}/estimators").json()
    assert choices["recorded"] is None and choices["refused"] == {
        "fp_ls": "needs the subject's calibrated gait fingerprint"
    }
    # as a session would run them: not the opt-in backup, nor the front ends deriving channels the log has
    left_out = registry.OPT_IN | registry.DERIVERS | {"fp_ls"}
    assert choices["default"] == [n for n in registry.ESTIMATORS if n not in left_out]
    strikes = {"heel_strike": ["hs_detector", "phase_ekf"]}
    assert choices["derived"] == {"tbe": strikes, "hs_backup": strikes}
    what_if = {"settings": {"torque_gain": 1.0}}
    r = client.post(f"/api/trials/{tid}/rerun", json={**what_if, "estimators": ["tbe"]})
    assert r.status_code == 422 and "tbe needs heel_strike" in r.json()["detail"], r.text
    ran = _rerun(client, tid, {**what_if, "estimators": ["hs_detector", "tbe"]})
    assert {k.split(".")[0] for k in ran if "." in k} == {"hs_detector", "tbe"}
