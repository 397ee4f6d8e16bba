"""Issue #23, points 7 and 8, in a real browser against the real server: one vocabulary, and reports that are right.

A simulated session records a first trial, walks on unrecorded for a while, records a second trial in which the
estimator driving the torque is switched to the timing-based estimate, and stops. Then:

- one vocabulary: no estimator's machine name (``phase_ekf``, ``tbe``, ``fp_avg``, ...) is in the text of the live
  page (its selector, data-health box, plots' titles and legends) or of the review page, nor in the trial's PDF;
  the review's marker labels sit inside their plots;
- the summary's duration is the recorded time (the trials' durations summed), shown beside the session's longer
  wall time; while the server reads the recordings the page shows how far it has got; the summary is kept;
- a trial's PDF is linked from its review page.

Screenshots at 1024x768: ``tests/e2e/artifacts/trust-reports-{live,summary,review}-1024x768.png``.
"""

from __future__ import annotations

import io
import json
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from pypdf import PdfReader

from gaitscope.sessions.registry import descriptors
from tests.e2e.accounts import call, session_time, simulated_session
from tests.e2e.pages import ARTIFACTS, Watched

playwright_api = pytest.importorskip("playwright.sync_api")
expect = playwright_api.expect

LABELS = {n: d.label for n, d in descriptors().items()}
#: Every registered estimator's machine name, as a word; but those that are words of a label too (``intent``, in
#: "Speed-change intent (seed 001)"), which English text may hold.
_IDS = [n for n in descriptors() if not any(re.search(rf"\b{re.escape(n)}\b", x, re.I) for x in LABELS.values())]
RAW_ID = re.compile(r"\b(" + "|".join(sorted(map(re.escape, _IDS), key=len, reverse=True)) + r")\b")


def _raw_ids(text: str) -> list[str]:
    return sorted(set(RAW_ID.findall(text)))


@pytest.fixture(scope="module")
def walked(server: str) -> Iterator[dict[str, Any]]:
    """A running simulated session: trial 1 (recorded from the start), ~3 s unrecorded, trial 2 with a switch
    of the primary to the timing-based estimate in it. Stopped by the last test that needs it running."""
    _, session = simulated_session(server, "VOC01", 1.2, 0.0, 400)
    sid = session["id"]
    t = session_time(server, sid, 3.0)
    first: dict[str, Any] = call(server, "POST", f"/api/sessions/{sid}/recording", {"action": "stop"})
    session_time(server, sid, t + 3.0)  # walked, not recorded
    call(server, "POST", f"/api/sessions/{sid}/recording", {"action": "start", "name": "second"})
    session_time(server, sid, t + 5.0)
    call(server, "PATCH", f"/api/sessions/{sid}/settings", {"primary": "tbe", "confirm": True})
    session_time(server, sid, t + 8.0)
    second = call(server, "POST", f"/api/sessions/{sid}/recording", {"action": "stop"})
    try:
        yield {"session": session, "first": first, "second": second}
    finally:
        if call(server, "GET", f"/api/sessions/{sid}")["state"] == "running":
            call(server, "POST", f"/api/sessions/{sid}/stop")


def _stopped(server: str, sid: int) -> None:
    if call(server, "GET", f"/api/sessions/{sid}")["state"] == "running":
        call(server, "POST", f"/api/sessions/{sid}/stop")


def test_live_page_names_no_estimator_by_its_machine_name(
    server: str, watched: Watched, walked: dict[str, Any]
) -> None:
    page = watched.page
    sid = walked["session"]["id"]
    page.goto(f"{server}/#/sessions/{sid}", wait_until="domcontentloaded")
    expect(page.get_by_test_id("health-primary")).to_have_text(LABELS["tbe"], timeout=20_000)
    expect(page.get_by_test_id("plot-phase")).to_contain_text(f"{LABELS['tbe']} (primary: drives the torque)")
    options = page.get_by_test_id("primary-select").locator("option")
    expect(options.first).to_be_attached()
    assert _raw_ids(" ".join(options.all_inner_texts())) == []
    assert set(options.all_inner_texts()) >= {LABELS["phase_ekf"], LABELS["tbe"]}
    page.wait_for_timeout(1500)  # a few batches drawn: legends and health filled
    assert _raw_ids(page.locator("body").inner_text()) == []
    page.screenshot(path=str(ARTIFACTS / "trust-reports-live-1024x768.png"))
    watched.check_clean()


def test_summary_shows_recorded_time_beside_wall_time_with_progress(
    server: str, watched: Watched, walked: dict[str, Any]
) -> None:
    page = watched.page
    sid = walked["session"]["id"]
    _stopped(server, sid)
    trials = call(server, "GET", f"/api/trials?session_id={sid}")
    assert len(trials) == 2
    # the server is made to answer slowly: the page shows the progress the server reports meanwhile
    held: list[Any] = []
    page.route(re.compile(rf"/api/sessions/{sid}/summary$"), lambda route: held.append(route))
    running = {
        "running": True,
        "cached": False,
        "progress": 0.4,
        "step": "reading the recordings: 800 of 2000 gait states",
    }
    page.route(re.compile(rf"/api/sessions/{sid}/summary/progress$"), lambda route: route.fulfill(json=running))
    page.goto(f"{server}/#/sessions/{sid}/summary", wait_until="domcontentloaded")
    bar = page.get_by_test_id("report-progress")
    expect(bar).to_be_visible()
    expect(bar).to_have_attribute("aria-valuenow", "40")
    expect(page.get_by_test_id("report-note")).to_contain_text("40 % (reading the recordings: 800 of 2000 gait states)")
    page.unroute(re.compile(rf"/api/sessions/{sid}/summary/progress$"))
    for route in held:
        route.continue_()  # the summary's own answer, now
    page.unroute(re.compile(rf"/api/sessions/{sid}/summary$"))
    summary = call(server, "GET", f"/api/sessions/{sid}/summary")
    recorded = sum(t["duration_s"] for t in trials)
    assert summary["duration_s"] == pytest.approx(recorded, abs=1e-3)
    assert summary["wall_s"] > recorded + 2.0  # ~3 s walked unrecorded
    expect(page.get_by_test_id("report-duration")).to_have_text(f"{summary['duration_s']:.1f} s")
    expect(page.get_by_test_id("report-wall")).to_have_text(f"{summary['wall_s']:.1f} s")
    expect(page.locator("dt", has_text="Recorded time (2 trials)")).to_be_visible()
    expect(page.get_by_test_id("report-progress")).to_be_hidden()
    expect(page.get_by_test_id("settings-primary")).to_have_text(LABELS["tbe"])
    expect(page.get_by_test_id("settings-change").first).to_contain_text(
        f"Torque follows {LABELS['phase_ekf']} → {LABELS['tbe']}"
    )
    # kept: asked again, it is ready without reading the recordings
    assert call(server, "GET", f"/api/sessions/{sid}/summary/progress") == {
        "running": False, "cached": True, "progress": 1.0, "step": "ready"
    }  # fmt: skip
    assert _raw_ids(page.locator("body").inner_text()) == []
    page.screenshot(path=str(ARTIFACTS / "trust-reports-summary-1024x768.png"), full_page=True)
    watched.check_clean()


def test_review_names_no_estimator_and_links_the_trials_pdf(
    server: str, watched: Watched, walked: dict[str, Any]
) -> None:
    page = watched.page
    sid = walked["session"]["id"]
    _stopped(server, sid)
    trial = walked["second"]
    page.goto(f"{server}/#/trials/{trial['id']}", wait_until="domcontentloaded")
    expect(page.get_by_test_id("review-title")).to_be_visible()
    plot = page.get_by_test_id("review-plot-torque")
    plot.scroll_into_view_if_needed()
    label = f"Torque follows {LABELS['phase_ekf']} → {LABELS['tbe']}"
    expect(plot).to_have_attribute(
        "data-marker-labels", re.compile(re.escape(json.dumps(label, ensure_ascii=False)[:-1]))
    )
    marks = json.loads(plot.get_attribute("data-marker-boxes") or "{}")
    assert marks["boxes"], marks  # the switch's label is written on the plot, inside it
    assert all(0 <= left <= right <= marks["width"] + 0.5 for left, right in marks["boxes"]), marks
    card = page.get_by_test_id("trial-export-card")
    card.scroll_into_view_if_needed()
    assert _raw_ids(page.locator("body").inner_text()) == []
    page.screenshot(path=str(ARTIFACTS / "trust-reports-review-1024x768.png"), full_page=True)
    with page.expect_download(timeout=60_000) as dl:
        card.get_by_test_id("export-pdf").click()
    assert dl.value.suggested_filename == f"gaitscope_VOC01_session{sid}_trial{trial['id']}.pdf"
    pdf = PdfReader(io.BytesIO(Path(dl.value.path()).read_bytes()))
    text = " ".join(" ".join(p.extract_text() or "" for p in pdf.pages).split())
    assert f"Trial second of session {sid}, VOC01" in text
    assert f"Torque follows {LABELS['phase_ekf']} → {LABELS['tbe']}" in text
    assert _raw_ids(text) == [], _raw_ids(text)
    watched.check_clean()
