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
        r = client.patch(f"/api/sessions/{s['id']}/settings", json={"torque_gain": 1.4, "actor": "local"})
        assert r.status_code == 200, r.text
        client.post(f"/api/sessions/{s['id']}/annotations", json={"text": "subject comfortable"})
        _wait(client, s["id"], 11.0)
        assert client.post(f"/api/sessions/{s['id']}/stop").status_code == 200
        yield client, s["id"]


def _export(client: TestClient, session_id: int, kind: str) -> tuple[dict[str, Any], bytes, list[float]]:
    r = client.post(f"/api/sessions/{session_id}/exports", json={"kind": kind})
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
    assert 11.0 <= s["duration_s"] <= 25.0
    # strides: ~0.9-1.4 s each over ~11 s of walking, the first one or two lost to the filters' start
    assert 6 <= s["strides"] <= 13 and len(s["profile"]) == s["strides"]
    assert sum(c["strides"] for c in s["conditions"]) == s["strides"]
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
    assert [r["text"] for r in s["settings_history"]] == ["Torque gain 1.00 -> 1.40, by local"]
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
    assert f"Duration {s['duration_s']:.1f} s" in text  # under a minute
    assert f"Strides {s['strides']}" in text
    assert "Torque gain 1.00 -> 1.40, by local" in text
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
    assert all(0.0 <= float(r["phase"]) < 1.0 for r in rows)
    assert seen == sorted(seen)  # progress only goes up


def test_export_errors(recorded: Any) -> None:
    client, _ = recorded
    assert client.post("/api/sessions/999/exports", json={"kind": "pdf"}).status_code == 404
    assert client.post("/api/sessions/1/exports", json={"kind": "docx"}).status_code == 422
    assert client.get("/api/exports/" + "0" * 32).status_code == 404
    assert client.get("/api/exports/../etc").status_code == 404
    assert client.get("/api/sessions/999/summary").status_code == 404


def test_summary_is_kept_until_the_session_changes(recorded: Any) -> None:
    client, sid = recorded
    first = client.get(f"/api/sessions/{sid}/summary").json()
    cache = client.app.state.summaries
    kept = cache[sid][1]
    assert client.get(f"/api/sessions/{sid}/summary").json() == first and cache[sid][1] is kept
    client.post(f"/api/sessions/{sid}/annotations", json={"text": "note added after the stop"})
    again = client.get(f"/api/sessions/{sid}/summary").json()
    assert cache[sid][1] is not kept and any(e["text"] == "note added after the stop" for e in again["events"])
    assert again["strides"] == first["strides"]
