"""A stopped session's summary, PDF report and CSV of estimates, through the real app, SQLite and a real
recorded session (a simulated walker at two speeds)."""

from __future__ import annotations

import csv
import io
import itertools
from typing import Any

import pytest
from fastapi.testclient import TestClient
from pypdf import PdfReader

from gaitscope.sessions.reports.estimates_csv import CSV_COLUMNS
from gaitscope.sessions.reports.pdf import FIGURE_TITLES
from gaitscope.sessions.reports.summary import MIN_CONDITION_STRIDES, SPEED_BIN, _bin
from tests.waiting import wait_until

TWO_SPEEDS = {
    "kind": "simulated",
    "protocol": [
        {"speed_m_s": 1.2, "incline_deg": 0.0, "strides": 5},
        {"speed_m_s": 0.8, "incline_deg": 0.0, "strides": 200},
    ],
    "rate_hz": 200,
    "loop": False,
}


def _wait(client: TestClient, session_id: int, seconds: float) -> None:
    runtime = client.app.state.ctx.manager.get(session_id)  # type: ignore[attr-defined]
    wait_until(lambda: runtime.samples >= 200 * seconds, seconds + 20, f"{seconds:g} s of samples")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """One app with one stopped session: ~11 s of walking, a torque-gain change, an annotation."""
    from gaitscope.server.app import create_app
    from gaitscope.server.settings import Settings

    tmp = tmp_path_factory.mktemp("reports")
    settings = Settings(
        data_dir=tmp / "data", demo=False, leg_view=False, allowed_hosts=["testserver"], disk_warn_mb=1,
        disk_stop_mb=1, upload_min_free_mb=1,
    )  # fmt: skip
    with TestClient(create_app(settings)) as client:
        sid = client.post("/api/subjects", json={"code": "RPT01", "leg_length_m": 0.9, "mass_kg": 70.0}).json()["id"]
        s = client.post("/api/sessions", json={"subject_id": sid, "source": TWO_SPEEDS}).json()
        _wait(client, s["id"], 4.0)
        raised = {"torque_gain": 1.4, "actor": "local", "confirm": True}
        r = client.patch(f"/api/sessions/{s['id']}/settings", json=raised)
        assert r.status_code == 200, r.text
        client.post(f"/api/sessions/{s['id']}/annotations", json={"text": "subject comfortable"})
        _wait(client, s["id"], 11.0)
        assert client.post(f"/api/sessions/{s['id']}/stop").status_code == 200
        yield client, s["id"]


def _export(
    client: TestClient, session_id: int, kind: str, trial_id: int | None = None
) -> tuple[dict[str, Any], bytes, list[float]]:
    url = f"/api/sessions/{session_id}/exports" if trial_id is None else f"/api/trials/{trial_id}/exports"
    r = client.post(url, json={"kind": kind})
    assert r.status_code == 202, r.text
    job = r.json()
    seen = [job["progress"]]

    def finished() -> bool:
        nonlocal job
        job = client.get(f"/api/exports/{job['id']}").json()
        seen.append(job["progress"])
        return bool(job["state"] != "running")

    if job["state"] == "running":
        wait_until(finished, 60.0, f"export job {job['id']}")
    assert job["state"] == "done", job
    r = client.get(f"/api/exports/{job['id']}/file")
    assert r.status_code == 200
    return job, r.content, seen


def test_summary_numbers(recorded: Any) -> None:
    client, sid = recorded
    s = client.get(f"/api/sessions/{sid}/summary").json()
    trials = client.get(f"/api/trials?session_id={sid}").json()
    assert s["subject_code"] == "RPT01" and s["state"] == "stopped" and s["source"] == "simulated walker"
    # recorded time: the sum of the trials' recorded durations; the wall time from start to stop beside it
    assert 11.0 <= s["duration_s"] <= 25.0 and s["duration_s"] == pytest.approx(sum(t["duration_s"] for t in trials))
    assert s["wall_s"] is not None and s["wall_s"] >= s["duration_s"] - 0.5
    # strides: ~0.9-1.4 s each over ~11 s of walking, the first one or two lost to the filters' start
    assert 6 <= s["strides"] <= 13 and len(s["profile"]) == s["strides"]
    # every stride is in a condition held, or walked while the protocol changed (1.2 m/s for ~3 strides: none)
    assert sum(c["strides"] for c in s["conditions"]) + s["transition_strides"] == s["strides"]
    assert all(c["strides"] >= MIN_CONDITION_STRIDES for c in s["conditions"])
    # the protocol's speeds only: the stride straddling the change (~1.0 m/s) makes no condition
    assert {c["speed_m_s"] for c in s["conditions"]} <= {1.2, 0.8} and s["conditions"]
    straddling = [p for p in s["profile"] if _bin(p["speed_m_s"], SPEED_BIN) not in (1.2, 0.8)]
    assert straddling and s["transition_strides"] >= len(straddling)
    assert s["profile"][0]["after_gap"] and not any(p["after_gap"] for p in s["profile"][1:])
    fast = [p["speed_m_s"] for p in s["profile"] if p["t"] < 4.0]
    slow = [p["speed_m_s"] for p in s["profile"] if p["t"] > 8.0]
    assert fast and slow and sum(fast) / len(fast) > sum(slow) / len(slow) + 0.15  # the walker slowed down
    assert all(abs(p["incline_deg"]) < 2.0 for p in s["profile"])
    assert 0.6 < s["mean_speed_m_s"] < 1.4
    assert s["mean_cadence_spm"] == pytest.approx(
        60 * s["strides"] / sum(p["duration_s"] for p in s["profile"]), rel=1e-3
    )
    h = s["health"]
    assert h["samples"] == sum(t["samples"] for t in trials) and h["rate_hz"] == pytest.approx(200, rel=0.02)
    assert h["gaps"] == 0 and h["missing_percent"] == 0.0
    assert [r["text"] for r in s["settings_history"]] == ["Torque gain 1.00 → 1.40, by local"]
    assert s["settings_start"]["torque_gain"] == 1.0 and s["settings_end"]["torque_gain"] == 1.4
    assert any(e["text"] == "subject comfortable" for e in s["events"])
    cond = s["conditions"][0]
    assert len(cond["percent"]) == 51 and {"torque_Nm", "thigh_angle_deg"} <= set(cond["signals"])
    assert 1 <= len(cond["overlays"]["torque_Nm"]) <= 12


def test_pdf_report_reads_back(recorded: Any) -> None:
    client, sid = recorded
    s = client.get(f"/api/sessions/{sid}/summary").json()
    job, data, _ = _export(client, sid, "pdf")
    assert job["filename"] == f"gaitscope_RPT01_session{sid}.pdf" and data[:5] == b"%PDF-"
    text = " ".join((page.extract_text() or "") for page in PdfReader(io.BytesIO(data)).pages)
    text = " ".join(text.split())
    assert f"Session {sid} of RPT01" in text
    assert f"Duration {s['duration_s']:.1f} s recorded in 1 trial" in text  # under a minute
    assert "Wall time" in text and "from start to stop" in text
    assert f"Strides {s['strides']}" in text
    assert "Torque gain 1.00 → 1.40, by local" in text
    assert "Torque follows Phase EKF (seed 000)" in text and "phase_ekf" not in text
    for caption in FIGURE_TITLES.values():
        assert caption in text  # every figure is there


def test_csv_of_estimates_parses(recorded: Any) -> None:
    client, sid = recorded
    trials = client.get(f"/api/trials?session_id={sid}").json()
    _, data, seen = _export(client, sid, "csv")
    rows = list(csv.DictReader(io.StringIO(data.decode("utf-8"))))
    assert tuple(rows[0]) == CSV_COLUMNS
    assert len(rows) == sum(t["samples"] for t in trials)
    t = [float(r["t"]) for r in rows]
    assert all(b > a for a, b in itertools.pairwise(t))
    strikes = sum(r["heel_strike"] == "1" for r in rows)
    assert strikes >= client.get(f"/api/sessions/{sid}/summary").json()["strides"]
    phases = [float(r["phase_percent"]) for r in rows if r["phase_percent"]]
    assert all(0.0 <= p < 100.0 for p in phases) and max(phases) > 90.0  # in %, as the dashboard shows it
    assert seen == sorted(seen)  # progress only goes up


def test_export_errors(recorded: Any) -> None:
    client, _ = recorded
    assert client.post("/api/sessions/999/exports", json={"kind": "pdf"}).status_code == 404
    assert client.post("/api/sessions/1/exports", json={"kind": "docx"}).status_code == 422
    assert client.get("/api/exports/" + "0" * 32).status_code == 404
    assert client.get("/api/exports/../etc").status_code == 404
    assert client.get("/api/sessions/999/summary").status_code == 404


def test_summary_is_kept_until_the_sessions_trials_change(recorded: Any) -> None:
    """Issue #23: the summary is made once and kept; new events are brought in without reading the recordings
    again; a change of the trials makes it again."""
    client, sid = recorded
    first = client.get(f"/api/sessions/{sid}/summary").json()
    summaries = client.app.state.summaries
    kept = summaries.kept[sid][1]
    assert client.get(f"/api/sessions/{sid}/summary/progress").json() == {
        "running": False, "cached": True, "progress": 1.0, "step": "ready"
    }  # fmt: skip
    assert client.get(f"/api/sessions/{sid}/summary").json() == first and summaries.kept[sid][1] is kept
    client.post(f"/api/sessions/{sid}/annotations", json={"text": "note added after the stop"})
    again = client.get(f"/api/sessions/{sid}/summary").json()
    assert summaries.kept[sid][1] is kept  # not made again
    assert any(e["text"] == "note added after the stop" for e in again["events"])
    assert again["strides"] == first["strides"]
    store = client.app.state.ctx.store
    trial = store.list_trials(sid)[0]
    store.finish_trial(trial.id, "recovered", trial.samples, trial.duration_s)
    try:
        assert client.get(f"/api/sessions/{sid}/summary/progress").json()["cached"] is False
        changed = client.get(f"/api/sessions/{sid}/summary").json()
        assert summaries.kept[sid][1] is not kept and changed["health"]["trials_recovered"] == 1
    finally:
        store.finish_trial(trial.id, trial.status, trial.samples, trial.duration_s)
    assert client.get("/api/sessions/999/summary/progress").status_code == 404


def test_summary_progress_while_it_is_made(recorded: Any) -> None:
    """The progress the waiting page shows: what the making reports, in gait states read."""
    from gaitscope.server.routes.reports import Summaries

    client, sid = recorded
    summaries = Summaries()
    summaries.making[sid] = (("x",), None)  # type: ignore[assignment]
    summaries.progress[sid] = (500, 2000)
    ctx = client.app.state.ctx
    state = summaries.state(ctx, sid)
    assert state.running and not state.cached and state.progress == 0.25
    assert state.step == "reading the recordings: 500 of 2000 gait states"


def test_one_trial_exports(recorded: Any) -> None:
    """Issue #23: a trial's PDF and CSV, as well as the session's."""
    client, sid = recorded
    trial = client.get(f"/api/trials?session_id={sid}").json()[0]
    job, data, _ = _export(client, sid, "pdf", trial["id"])
    assert job["trial_id"] == trial["id"] and job["filename"] == f"gaitscope_RPT01_session{sid}_trial{trial['id']}.pdf"
    text = " ".join(" ".join((page.extract_text() or "") for page in PdfReader(io.BytesIO(data)).pages).split())
    assert f"Trial {trial['name']} of session {sid}, RPT01" in text
    job, data, _ = _export(client, sid, "csv", trial["id"])
    rows = list(csv.DictReader(io.StringIO(data.decode("utf-8"))))
    assert len(rows) == trial["samples"] and {r["trial_id"] for r in rows} == {str(trial["id"])}
    assert client.post("/api/trials/999/exports", json={"kind": "pdf"}).status_code == 404


def test_a_sessions_pdf_typesets_the_kept_summary(recorded: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue #23: a summary made once is not made again for the PDF (the recordings are not read again)."""
    from gaitscope.sessions.reports import jobs

    client, sid = recorded
    client.get(f"/api/sessions/{sid}/summary")  # made and kept

    def not_again(*args: Any, **kw: Any) -> Any:
        raise AssertionError("the recordings were read again")

    monkeypatch.setattr(jobs, "session_summary", not_again)
    _, data, _ = _export(client, sid, "pdf")
    assert data[:5] == b"%PDF-"
    trial = client.get(f"/api/trials?session_id={sid}").json()[0]
    r = client.post(f"/api/trials/{trial['id']}/exports", json={"kind": "pdf"})  # a trial's: made, so it fails here
    wait_until(lambda: client.get(f"/api/exports/{r.json()['id']}").json()["state"] != "running", 30.0, "the job")
    assert client.get(f"/api/exports/{r.json()['id']}").json()["error"] == "the recordings were read again"
