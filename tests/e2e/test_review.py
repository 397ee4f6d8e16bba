"""Review (``#/trials/{id}``) in a real browser against the real server: an experimenter reviews a trial a
simulated session recorded, with a torque-gain change made by another clinician during it.

Opened while it still records, the page says so with a link to the live session, and opens the review by
itself once the recording stops (never an error above empty plots). Then: the re-run form says a re-run
starts from the settings that ran and lists the recorded change in words, which the timeline draws as a
labelled marker; playback (play, pause, speeds) moves the cursor, and the keys (space, arrows, + and -) work
except while typing in a field; notes at a time and over a span are added, drawn, listed, kept on reload and
deleted by their author only; and an A/B comparison of three named re-runs shows their plots and figures,
errors against the simulated walk's ground truth included. Screenshots at 1440x900, 1024x768 and 390x844:
``tests/e2e/artifacts/review-*.png``. The fixtures are ``conftest.py``'s (this module gets its own server).
"""

from __future__ import annotations

import json
import re
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import pytest

from tests.e2e.accounts import call, session_time, simulated_session
from tests.e2e.pages import ARTIFACTS, Watched, wait_responsive

if TYPE_CHECKING:
    from playwright.sync_api import Page

playwright_api = pytest.importorskip("playwright.sync_api")
expect = playwright_api.expect


VIEWPORTS = ((1440, 900), (1024, 768), (390, 844))


@pytest.fixture(scope="module")
def recording(server: str) -> Iterator[dict[str, Any]]:
    """A running simulated session (100 Hz) whose first trial is recording."""
    _, session = simulated_session(server, "RV01", 1.2, 0.0, 300)
    trial = call(server, "GET", f"/api/trials?session_id={session['id']}")[0]
    assert trial["status"] == "recording"
    try:
        yield {"session": session, "trial": trial}
    finally:
        if call(server, "GET", f"/api/sessions/{session['id']}")["state"] == "running":
            call(server, "POST", f"/api/sessions/{session['id']}/stop")


def _expect_labels(page: Page, testid: str, *labels: str) -> None:
    """The plot `testid` draws markers labelled `labels` (the labels its last draw wrote on its element)."""
    for label in labels:
        text = re.escape(json.dumps(label, ensure_ascii=False))
        page.get_by_test_id(testid).scroll_into_view_if_needed()  # a plot out of sight draws when it comes in
        expect(page.get_by_test_id(testid)).to_have_attribute("data-marker-labels", re.compile(text))


def _leg_view_started(page: Page) -> None:
    """Let the leg view start: headless chromium draws its 3D in software, which holds the page for many
    seconds the first time the view comes in sight (not the review's doing; timing the playback needs it done)."""
    page.get_by_test_id("leg-card").scroll_into_view_if_needed()
    wait_responsive(page, 60.0)
    page.get_by_test_id("review-title").scroll_into_view_if_needed()


def _cursor(page: Page) -> float:
    return float(page.get_by_test_id("cursor-time").inner_text())


def test_review(server: str, watched: Watched, recording: dict[str, Any]) -> None:
    page = watched.page
    session, trial = recording["session"], recording["trial"]
    tid = trial["id"]

    # --- 4. still recording: a clear message and a link to the live session, no error, no empty plots ----
    page.goto(f"{server}/#/trials/{tid}")
    expect(page.get_by_test_id("review-recording-note")).to_contain_text("Still recording")
    expect(page.get_by_test_id("review-open-live")).to_have_attribute("href", f"#/sessions/{session['id']}")
    expect(page.get_by_test_id("review-error")).to_be_hidden()
    expect(page.get_by_test_id("timeline")).to_be_hidden()
    page.screenshot(path=str(ARTIFACTS / "review-recording.png"))
    # another clinician raises the gain during the trial; then the recording stops
    t0 = session_time(server, session["id"])
    session_time(server, session["id"], t0 + 2.5)
    call(
        server, "PATCH", f"/api/sessions/{session['id']}/settings", {"torque_gain": 1.3, "confirm": True}, user="admin"
    )
    session_time(server, session["id"], t0 + 6.5)
    stopped = call(server, "POST", f"/api/sessions/{session['id']}/recording", {"action": "stop"})
    assert stopped["status"] == "finished" and stopped["id"] == tid
    # the page opens the review by itself
    expect(page.get_by_test_id("review-recording")).to_be_hidden(timeout=10_000)
    expect(page.get_by_test_id("trial-info")).to_contain_text("finished")
    expect(page.get_by_test_id("review-stride-count")).to_contain_text("strides", timeout=30_000)  # the trial loaded
    _leg_view_started(page)

    # --- 1. the re-run starts from what ran; the recorded change in words, on the timeline too ------------
    expect(page.get_by_test_id("rerun-start")).to_contain_text("A re-run starts from the settings that ran")
    change = page.get_by_test_id("rerun-change")
    expect(change).to_have_count(1)
    expect(change).to_contain_text("Torque gain 1.00 → 1.30, by admin")
    expect(page.get_by_test_id("rerun-changes")).not_to_contain_text("torque_gain")
    _expect_labels(page, "timeline", "Torque gain 1.00 → 1.30, by admin")
    _expect_labels(page, "review-plot-torque", "Torque gain 1.00 → 1.30, by admin")

    # --- 3. playback: play, pause, speed; keys; typing in a field is not a shortcut ------------------------
    t_end = float(page.get_by_test_id("scrubber").get_attribute("max") or "nan")
    assert 5.0 < t_end < 12.0
    t_start = float(page.get_by_test_id("scrubber").get_attribute("min") or "nan")

    def play_for(ms: int) -> tuple[float, float, float]:
        """Play for about `ms` ms: the cursor's advance and the least and most wall time it can have played."""
        page.get_by_test_id("scrubber").fill(f"{t_start:.2f}")  # from the start: room to play
        before = _cursor(page)
        t0 = time.monotonic()
        page.get_by_test_id("play").click()
        t1 = time.monotonic()
        expect(page.get_by_test_id("playback")).to_have_attribute("data-state", "playing")
        page.wait_for_timeout(ms)
        t2 = time.monotonic()
        page.get_by_test_id("play").click()
        t3 = time.monotonic()
        expect(page.get_by_test_id("playback")).to_have_attribute("data-state", "paused")
        return _cursor(page) - before, t2 - t1, t3 - t0

    moved, least, most = play_for(1000)
    assert 0.8 * least - 0.1 < moved < 1.1 * most + 0.1, (moved, least, most)  # real time at 1x
    page.get_by_test_id("play-speed").select_option("4")
    moved, least, most = play_for(500)
    assert 4 * 0.8 * least - 0.2 < moved < 4 * 1.1 * most + 0.2, (moved, least, most)  # four times faster
    page.get_by_test_id("play-speed").select_option("0.5")
    page.get_by_test_id("review-title").click()  # focus off the controls: the keys are the review's
    page.keyboard.press("Space")
    expect(page.get_by_test_id("playback")).to_have_attribute("data-state", "playing")
    page.wait_for_timeout(600)
    page.keyboard.press("Space")
    expect(page.get_by_test_id("playback")).to_have_attribute("data-state", "paused")
    here = round(t_end / 2, 2)  # a known place to step from (playback may have reached the end)
    page.get_by_test_id("scrubber").fill(f"{here:.2f}")
    expect(page.get_by_test_id("cursor-time")).to_have_text(f"{here:.2f}")
    page.get_by_test_id("review-title").click()
    page.keyboard.press("ArrowRight")
    expect(page.get_by_test_id("cursor-time")).to_have_text(f"{here + 0.1:.2f}")
    page.keyboard.press("ArrowLeft")
    page.keyboard.press("ArrowLeft")
    expect(page.get_by_test_id("cursor-time")).to_have_text(f"{here - 0.1:.2f}")
    page.keyboard.press("+")
    expect(page.get_by_test_id("zoom-to")).not_to_have_value(f"{t_end:.2f}")
    width = float(page.get_by_test_id("zoom-to").input_value()) - float(page.get_by_test_id("zoom-from").input_value())
    assert width == pytest.approx(t_end / 2, abs=0.2)
    page.keyboard.press("-")
    expect(page.get_by_test_id("zoom-to")).to_have_value(f"{t_end:.2f}")
    note = page.get_by_test_id("note-text")
    note.fill("left foot scuffs")
    note.press("Space")
    note.press("ArrowLeft")
    note.press("+")
    expect(page.get_by_test_id("playback")).to_have_attribute("data-state", "paused")
    expect(page.get_by_test_id("cursor-time")).to_have_text(f"{here - 0.1:.2f}")
    expect(note).to_have_value("left foot scuffs+ ")  # typed: the space, the caret moved back, the plus

    # --- 3. notes: at the cursor, over a span; listed, drawn, kept; deleted by their author only ----------
    note.fill("left foot scuffs")
    page.get_by_test_id("note-at-cursor").click()
    expect(page.get_by_test_id("note-from")).to_have_value(f"{here - 0.1:.2f}")
    page.get_by_test_id("note-add").click()
    rows = page.get_by_test_id("note-row")
    expect(rows).to_have_count(1)
    page.get_by_test_id("note-text").fill("turns to talk")
    page.get_by_test_id("note-from").fill("1")
    page.get_by_test_id("note-span").check()
    page.get_by_test_id("note-to").fill("0.5")
    page.get_by_test_id("note-add").click()
    expect(page.get_by_test_id("note-error")).to_have_text("The span must end after it starts.")
    page.get_by_test_id("note-to").fill("2.5")
    page.get_by_test_id("note-add").click()
    expect(rows).to_have_count(2)
    expect(rows.filter(has_text="turns to talk")).to_contain_text("1.00–2.50 s turns to talk by clinician")
    scuffs = rows.filter(has_text="left foot scuffs")
    expect(scuffs).to_contain_text(f"{here - 0.1:.2f} s left foot scuffs by clinician")
    times = [float(t.split("–")[0].split()[0]) for t in rows.get_by_test_id("note-go").all_inner_texts()]
    assert times == sorted(times)  # listed by time
    _expect_labels(page, "timeline", "Note: turns to talk", "Note: left foot scuffs")
    # someone else's note: listed, not deletable here
    call(server, "POST", f"/api/trials/{tid}/annotations", {"t": 3.0, "text": "check the strap"}, user="admin")
    page.reload()
    expect(rows).to_have_count(3, timeout=20_000)
    _leg_view_started(page)
    theirs = rows.filter(has_text="check the strap")
    expect(theirs.get_by_test_id("note-delete")).to_be_disabled()
    expect(theirs.get_by_test_id("note-delete")).to_have_attribute("title", "Only admin may delete it")
    rows.filter(has_text="turns to talk").get_by_test_id("note-delete").click()
    expect(rows).to_have_count(2)
    saved = call(server, "GET", f"/api/trials/{tid}/annotations")
    assert sorted(n["text"] for n in saved) == ["check the strap", "left foot scuffs"]
    rows.filter(has_text="check the strap").get_by_test_id("note-go").click()
    expect(page.get_by_test_id("cursor-time")).to_have_text("3.00")

    # --- 2. A/B: three named re-runs side by side, their difference, strides and figures -----------------
    page.get_by_test_id("ab-run-1-name").fill("gain 0.6")
    page.get_by_test_id("ab-run-1-torque_gain").fill("0.6")
    page.get_by_test_id("ab-add").click()
    page.get_by_test_id("ab-run-2-name").fill("gain 0.6")
    page.get_by_test_id("ab-compare").click()
    expect(page.get_by_test_id("ab-error")).to_have_text('Two re-runs are named "gain 0.6": give each its own name.')
    page.get_by_test_id("ab-run-2-name").fill("noisier sensors")
    page.get_by_test_id("ab-run-2-measurement_noise_scale").fill("3")
    page.get_by_test_id("ab-compare").click()
    expect(page.get_by_test_id("ab-status")).to_contain_text("Compared 3 re-runs", timeout=90_000)
    figures = page.get_by_test_id("ab-figures-row")
    expect(figures).to_have_count(3)
    expect(figures.nth(0)).to_contain_text("A: as recorded")
    expect(figures.nth(1)).to_contain_text("gain 0.6")
    expect(page.get_by_test_id("ab-truth")).to_contain_text("the simulated walk (cohort subject 0, seed 7)")
    peak = [float(figures.nth(k).locator("[data-key='peak_torque_Nm']").inner_text()) for k in range(3)]
    assert peak[1] < 0.8 * peak[0], peak  # 0.6 against the recorded 1.0 then 1.3
    for k in range(3):
        strides = int(figures.nth(k).locator("[data-key='strides']").inner_text())
        rate = float(figures.nth(k).locator("[data-key='mean_phase_rate_1_s']").inner_text())
        error = float(figures.nth(k).locator("[data-key='phase_rmse_pct']").inner_text())
        assert strides >= 3 and 0.6 < rate < 1.4 and 0 <= error < 10, (k, strides, rate, error)
    for plot in ("torque", "phase", "diff", "stride"):
        expect(page.get_by_test_id(f"ab-plot-{plot}").locator("canvas")).to_be_visible()
    expect(page.get_by_test_id("ab-plot-diff").locator(".u-legend")).to_contain_text("gain 0.6 − A: as recorded")
    stride_legend = page.get_by_test_id("ab-plot-stride").locator(".u-legend .u-series:visible")
    expect(stride_legend).to_have_count(4)  # % of stride, and each re-run once (its SD is its band)
    expect(stride_legend.nth(3)).to_contain_text("noisier sensors")
    _expect_labels(page, "ab-plot-torque", "Torque gain 1.00 → 1.30, by admin", "Note: check the strap")

    # --- screenshots at the three sizes; nothing wider than the phone's screen ---------------------------
    for w, hgt in VIEWPORTS:
        page.set_viewport_size({"width": w, "height": hgt})
        page.wait_for_timeout(400)
        overflow = page.evaluate("() => document.documentElement.scrollWidth - window.innerWidth")
        assert overflow <= 1, f"the review is {overflow} px wider than a {w} px screen"
        page.screenshot(path=str(ARTIFACTS / f"review-{w}x{hgt}.png"), full_page=True)
        page.get_by_test_id("ab-card").screenshot(path=str(ARTIFACTS / f"review-ab-{w}x{hgt}.png"))
    watched.check_clean()
