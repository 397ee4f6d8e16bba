"""People, sessions, reports (issue #12 §4) in a real browser against the real server.

Set up through the REST API: three subjects, and a simulated session of one of them that walks about 9 s at
two speeds with a torque-gain change, then stops. In the browser: the subjects page (search, sort, a subject's
sessions and trials with dates and durations); the stopped session's summary (duration, strides, settings
history, stride curves per condition, data health, events) and both exports, downloaded and read back (the PDF
with pypdf, the CSV parsed); a bad CSV upload refused naming its row and column; a recording cut off before it
was finished refused as recoverable, and recovered by the button. Screenshots ``people-*.png`` at 1440x900,
1024x768 and 390x844 go to ``tests/e2e/artifacts/``. The fixtures are ``conftest.py``'s (this module gets
its own server).
"""

from __future__ import annotations

import csv
import io
import json
import re
from pathlib import Path
from typing import Any

import pytest

from tests.e2e.accounts import client, session_time
from tests.e2e.pages import ARTIFACTS, Watched

playwright_api = pytest.importorskip("playwright.sync_api")
expect = playwright_api.expect


VIEWPORTS = {"1440x900": (1440, 900), "1024x768": (1024, 768), "390x844": (390, 844)}
WALK = {
    "kind": "simulated",
    "protocol": [
        {"speed_m_s": 1.2, "incline_deg": 0.0, "strides": 4},
        {"speed_m_s": 0.8, "incline_deg": 0.0, "strides": 200},
    ],
    "rate_hz": 200,
    "loop": False,
}


def _call(base: str, method: str, path: str, body: Any = None) -> Any:
    """A REST call as the clinician: the JSON answer, or the bytes of one that is not JSON (a download)."""
    raw = client(base).raw(method, path, body)
    try:
        return json.loads(raw) if raw else raw
    except (UnicodeDecodeError, ValueError):
        return raw


@pytest.fixture(scope="module")
def people(server: str) -> dict[str, Any]:
    """Subjects PPL-B, PPL-A, PPL-C (created in that order) and a stopped, recorded session of PPL-A."""
    ids = {}
    for code in ("PPL-B", "PPL-A", "PPL-C"):
        ids[code] = _call(server, "POST", "/api/subjects", {"code": code, "leg_length_m": 0.9, "mass_kg": 70.0})["id"]
    s = _call(server, "POST", "/api/sessions", {"subject_id": ids["PPL-A"], "source": WALK})
    session_time(server, s["id"], 4.0)
    _call(server, "PATCH", f"/api/sessions/{s['id']}/settings", {"torque_gain": 1.3, "confirm": True})
    session_time(server, s["id"], 9.0)
    _call(server, "POST", f"/api/sessions/{s['id']}/stop")
    trials = _call(server, "GET", f"/api/trials?session_id={s['id']}")
    return {"subjects": ids, "session": s["id"], "trials": trials}


def _codes(page: Any) -> list[str]:
    return [c for c in page.get_by_test_id("subject-row").evaluate_all("rows => rows.map(r => r.dataset.code)")
            if c.startswith("PPL-")]  # fmt: skip


def test_subjects_page_search_and_sort(server: str, watched: Watched, people: dict[str, Any]) -> None:
    page = watched.page
    ARTIFACTS.mkdir(exist_ok=True)
    page.goto(f"{server}/#/")
    page.get_by_test_id("nav-subjects").click()
    page.wait_for_url(re.compile(r"#/subjects$"))
    expect(page.get_by_test_id("subjects-count")).to_have_text("4 subjects.")  # the demo subject too
    assert _codes(page) == ["PPL-A", "PPL-B", "PPL-C"]  # by code, the default
    page.get_by_test_id("subjects-sort").select_option("newest")
    assert _codes(page) == ["PPL-C", "PPL-A", "PPL-B"]
    page.get_by_test_id("subjects-sort").select_option("recent")
    assert _codes(page)[0] == "PPL-A"  # the only one of them with a session
    page.get_by_test_id("subjects-search").fill("ppl-b")
    expect(page.get_by_test_id("subjects-count")).to_have_text("1 of 4 subjects match “ppl-b”.")
    expect(page.get_by_test_id("subject-details").locator("summary")).to_have_text(
        "Sessions and trials (0 sessions, 0 trials)"
    )
    assert _codes(page) == ["PPL-B"]
    page.get_by_test_id("subjects-search").fill("ppl-a")
    row = page.locator("[data-testid=subject-row][data-code='PPL-A']")
    row.get_by_test_id("subject-details").locator("summary").click()
    session = row.locator(f"[data-testid=subject-session][data-id='{people['session']}']")
    expect(session).to_be_visible()
    assert re.fullmatch(r"\d+(\.\d) s|\d+ min \d\d s", session.get_by_test_id("session-duration").inner_text())
    assert re.fullmatch(r"\d{4}-\d\d-\d\d \d\d:\d\d", session.get_by_test_id("session-date").inner_text())
    trial = people["trials"][0]
    expect(session.get_by_test_id("subject-trial")).to_contain_text(trial["name"])
    expect(session.get_by_test_id("subject-trial")).to_contain_text(f"{trial['duration_s']:.1f} s")
    page.get_by_test_id("subjects-search").fill("")
    for name, (w, h) in VIEWPORTS.items():
        page.set_viewport_size({"width": w, "height": h})
        page.wait_for_timeout(200)
        page.screenshot(path=str(ARTIFACTS / f"people-subjects-{name}.png"), full_page=True)
    watched.check_clean()


def test_summary_and_exports(server: str, watched: Watched, people: dict[str, Any], tmp_path: Path) -> None:
    from pypdf import PdfReader

    page = watched.page
    sid = people["session"]
    summary = _call(server, "GET", f"/api/sessions/{sid}/summary")
    page.goto(f"{server}/#/")
    page.get_by_test_id(f"session-summary-{sid}").click()
    page.wait_for_url(re.compile(rf"#/sessions/{sid}/summary$"))
    expect(page.get_by_test_id("report-title")).to_have_text(f"Session {sid} of PPL-A: summary")
    expect(page.get_by_test_id("report-duration")).to_have_text(f"{summary['duration_s']:.1f} s")  # under a minute
    expect(page.get_by_test_id("report-strides")).to_have_text(str(summary["strides"]))
    assert summary["strides"] >= 4
    expect(page.get_by_test_id("settings-change")).to_have_text("Torque gain 1.00 → 1.30, by clinician")
    expect(page.get_by_test_id("health-rate")).to_contain_text("Hz")
    expect(page.get_by_test_id("profile-speed").locator("canvas")).to_be_visible()
    expect(page.get_by_test_id("overlay-plot").locator("canvas")).to_be_visible()
    expect(page.get_by_test_id("overlay-caption")).to_contain_text("Assistance torque over the stride")
    page.get_by_test_id("overlay-signal").select_option("thigh_angle_deg")
    expect(page.get_by_test_id("overlay-caption")).to_contain_text("Thigh angle over the stride")
    expect(page.get_by_test_id("report-events").get_by_test_id("event-row").first).to_be_visible()

    with page.expect_download(timeout=60_000) as dl:
        page.get_by_test_id("export-pdf").click()
    pdf = tmp_path / "report.pdf"
    dl.value.save_as(pdf)
    assert dl.value.suggested_filename == f"gaitscope_PPL-A_session{sid}.pdf"
    text = " ".join(" ".join(p.extract_text() or "" for p in PdfReader(pdf).pages).split())
    assert f"Session {sid} of PPL-A" in text and f"Duration {summary['duration_s']:.1f} s" in text
    assert "Torque gain 1.00 → 1.30, by clinician" in text and "Speed profile" in text
    expect(page.get_by_test_id("export-done")).to_contain_text("Ready")

    # An export of a long session takes seconds: here its status answers "running" (the server's own answer,
    # held back) until the page has shown the progress and what the job is doing, then the real answer.
    held = {"on": True}

    def hold(route: Any) -> None:
        resp = route.fetch()
        job = resp.json()
        if held["on"]:
            job |= {"state": "running", "progress": 0.4, "step": "writing the estimates"}
        route.fulfill(response=resp, json=job)

    page.route(re.compile(r"/api/exports/[0-9a-f]{32}$"), hold)
    with page.expect_download(timeout=60_000) as dl:
        page.get_by_test_id("export-csv").click()
        bar = page.get_by_test_id("export-progress")
        expect(bar).to_be_visible()  # after a second
        expect(bar).to_have_attribute("aria-valuenow", "40")
        expect(page.get_by_test_id("export-step")).to_have_text("40 % · writing the estimates")
        held["on"] = False
    expect(page.get_by_test_id("export-progress")).to_be_hidden()
    page.unroute(re.compile(r"/api/exports/[0-9a-f]{32}$"))
    rows = list(csv.DictReader(io.StringIO(Path(dl.value.path()).read_text(encoding="utf-8"))))
    assert len(rows) == sum(t["samples"] for t in people["trials"]) and float(rows[-1]["t"]) > float(rows[0]["t"])

    for name, (w, h) in VIEWPORTS.items():
        page.set_viewport_size({"width": w, "height": h})
        page.wait_for_timeout(300)
        page.screenshot(path=str(ARTIFACTS / f"people-summary-{name}.png"), full_page=True)
    watched.check_clean()


def test_upload_errors_and_recovery(server: str, watched: Watched, people: dict[str, Any], tmp_path: Path) -> None:
    page = watched.page
    watched.allow_refusal(422, r"/api/uploads/\w+/finish$")
    page.goto(f"{server}/#/")
    subject = str(people["subjects"]["PPL-B"])
    page.get_by_test_id("upload-subject").select_option(subject)

    bad = tmp_path / "walk.csv"
    bad.write_text("time_s,foot_angle_deg\n0.00,10\n0.01,11\n0.02,eleven\n0.03,12\n", encoding="utf-8")
    page.get_by_test_id("upload-file").set_input_files(str(bad))
    page.get_by_test_id("upload-submit").click()
    expect(page.get_by_test_id("upload-error")).to_have_text(
        "The file was not accepted: walk.csv, row 4, column foot_angle_deg: not a number: 'eleven'",
        timeout=60_000,  # the first import starts the server's import worker process
    )
    expect(page.get_by_test_id("upload-recover")).to_be_hidden()

    # a recording cut off before it was finished (the server's own file, its last 30 % gone)
    trial = people["trials"][0]
    whole = _call(server, "GET", f"/api/trials/{trial['id']}/download")
    cut = tmp_path / "cut_off.mcap"
    cut.write_bytes(whole[: int(len(whole) * 0.7)])
    page.get_by_test_id("upload-file").set_input_files(str(cut))
    page.get_by_test_id("upload-submit").click()
    error = page.get_by_test_id("upload-error")
    expect(error).to_contain_text("cut_off.mcap: the MCAP file is incomplete (its recording was never finished")
    expect(error).to_contain_text("gaitscope can recover what was recorded")
    assert "/" not in error.inner_text().split("accepted: ")[1].split(":")[0]  # the file's name, never a path
    expect(page.get_by_test_id("upload-recover")).to_be_visible()
    for name, (w, h) in VIEWPORTS.items():
        page.set_viewport_size({"width": w, "height": h})
        page.wait_for_timeout(200)
        page.get_by_test_id("upload-form").screenshot(path=str(ARTIFACTS / f"people-upload-{name}.png"))
    page.get_by_test_id("upload-recover").click()
    page.wait_for_url(re.compile(r"#/trials/\d+$"), timeout=60_000)
    new_id = int(page.url.rsplit("/", 1)[1])
    recovered = _call(server, "GET", f"/api/trials/{new_id}")
    assert recovered["status"] == "uploaded" and recovered["name"] == "cut_off.mcap"
    assert 0.3 * trial["duration_s"] < recovered["duration_s"] < trial["duration_s"]
    watched.check_clean()
