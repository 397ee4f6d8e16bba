"""Safety in sight and plots you can read (issue #23, points 3 and 5; the header of point 9).

In Debian chromium against the real server: at 1440x900 and 1024x768 the live page's first screen (no
scrolling) holds the session's state and its Stop, LIVE, the recording state and the figures (phase, incline,
stride length, speed, torque, intent); the phone puts Stop and LIVE first; the header says REC while any trial
of the session records (started and stopped by another client here); Space pauses and resumes the live plots
(not while typing); each key plot's data area (uPlot's ``.u-over``) is at least 60 % of its card; hovering moves
nothing; a plot enlarges and Esc returns it; a named layout survives a reload and goes out and back in as JSON.
Screenshots: ``tests/e2e/artifacts/trust-layout-*.png`` (live and review, at the three sizes).
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from playwright import sync_api as playwright_api

from tests.e2e.accounts import call
from tests.e2e.pages import ARTIFACTS, Watched, watch

expect = playwright_api.expect

SIM = {"kind": "simulated", "protocol": [{"speed_m_s": 1.2, "incline_deg": 5.0, "strides": 400}], "rate_hz": 100}
KEY_PLOTS = ("plot-phase", "plot-torque", "plot-phase_rate", "plot-incline")
#: What a clinician decides from, in the first screen (issue #23, point 3).
FIRST_SCREEN = ("session-state", "session-stop", "live-indicator", "live-recording", "summary-phase", "summary-incline",
                "summary-stride-length", "summary-speed", "summary-peak-torque", "summary-intent")  # fmt: skip
SIZES = ((1440, 900), (1024, 768), (390, 844))

_STARTED: list[tuple[str, int]] = []


@pytest.fixture(autouse=True)
def _stop_sessions() -> Iterator[None]:
    yield
    while _STARTED:
        base, sid = _STARTED.pop()
        if call(base, "GET", f"/api/sessions/{sid}")["state"] == "running":
            call(base, "POST", f"/api/sessions/{sid}/stop")


def _session(server: str, code: str) -> int:
    subject = call(server, "POST", "/api/subjects", {"code": code, "leg_length_m": 0.9, "mass_kg": 70.0})
    sid = int(call(server, "POST", "/api/sessions", {"subject_id": subject["id"], "source": SIM})["id"])
    _STARTED.append((server, sid))
    return sid


def _page(browser: playwright_api.Browser, server: str, size: tuple[int, int]) -> Iterator[Watched]:
    context, w = watch(browser, server, viewport=size, timeout_ms=20_000)
    try:
        yield w
    finally:
        context.close()


def _open(w: Watched, server: str, sid: int, fresh: bool = True) -> playwright_api.Page:
    page = w.page
    page.goto(f"{server}/#/sessions/{sid}", wait_until="domcontentloaded")
    if fresh:  # the standard layout
        page.evaluate("() => localStorage.clear()")
        page.reload(wait_until="domcontentloaded")
    expect(page.get_by_test_id("connection")).to_have_text("connected", timeout=40_000)  # a busy machine: take time
    expect(page.get_by_test_id("live-indicator")).not_to_have_text("NO DATA", timeout=30_000)
    return page


def _inside(box: dict[str, float] | None, width: int, height: int) -> bool:
    return (
        box is not None
        and box["width"] > 0
        and box["x"] >= 0
        and box["y"] >= 0
        and box["x"] + box["width"] <= width
        and box["y"] + box["height"] <= height
    )


def _boxes(page: playwright_api.Page, selector: str) -> list[list[float]]:
    """The boxes [x, y, w, h] of every element matching ``selector`` (rounded to a tenth of a pixel)."""
    boxes: list[list[float]] = page.evaluate(
        f"() => [...document.querySelectorAll({json.dumps(selector)})]"
        ".map((e) => { const r = e.getBoundingClientRect();"
        " return [r.x, r.y, r.width, r.height].map((v) => Math.round(v * 10) / 10); })"
    )
    return boxes


def _data_share(page: playwright_api.Page, testid: str) -> float:
    """The share of the plot card ``testid`` its data area (uPlot's ``.u-over``) takes."""
    share: float = page.evaluate(
        f"() => {{ const c = document.querySelector('[data-testid={testid}]').getBoundingClientRect();"
        f" const o = document.querySelector('[data-testid={testid}] .u-over').getBoundingClientRect();"
        " return (o.width * o.height) / (c.width * c.height); }"
    )
    return share


def _paused(page: playwright_api.Page) -> bool:
    return page.get_by_test_id("live-pause").get_attribute("aria-pressed") == "true"


# --- point 3: safety in sight ------------------------------------------------------------------------------
def test_first_screen_holds_what_a_clinician_decides_from(server: str, browser: playwright_api.Browser) -> None:
    sid = _session(server, "TL01")
    for width, height in SIZES:
        for w in _page(browser, server, (width, height)):
            page = _open(w, server, sid)
            expect(page.get_by_test_id("live-recording")).to_contain_text("REC trial")  # the first trial records
            assert page.evaluate("() => document.documentElement.scrollWidth") <= width  # nothing runs off sideways
            assert page.evaluate("() => window.scrollY") == 0
            boxes = {t: page.get_by_test_id(t).bounding_box() for t in FIRST_SCREEN}
            if width >= 1024:  # a tablet and a desktop: all of it without scrolling, and the four key plots' data
                assert {t: b for t, b in boxes.items() if not _inside(b, width, height)} == {}, (width, boxes)
                for testid in KEY_PLOTS:
                    assert _data_share(page, testid) >= 0.6, (width, testid, _data_share(page, testid))
                assert _inside(page.get_by_test_id("plot-phase").locator(".u-over").bounding_box(), width, height)
            else:  # a phone: one column, Stop and LIVE first, before the plots and the health's figures
                for t in ("session-stop", "live-indicator", "live-recording"):
                    assert _inside(boxes[t], width, height), (t, boxes[t])
                phase = page.get_by_test_id("plot-phase").bounding_box()
                health = page.get_by_test_id("health").bounding_box()
                assert phase and health and boxes["session-stop"] and boxes["live-indicator"]
                assert boxes["session-stop"]["y"] < health["y"] < phase["y"]
                assert boxes["live-indicator"]["y"] < health["y"]
            header = page.locator(".topbar").bounding_box()
            assert header
            for badge in ("header-recording", "server-status", "user-badge"):  # whole, not cut off (point 9)
                box = page.get_by_test_id(badge).bounding_box()
                assert _inside(box, width, int(header["y"] + header["height"]) + 1), (width, badge, box)
            page.screenshot(path=str(ARTIFACTS / f"trust-layout-live-{width}.png"))
            w.check_clean()


def test_header_says_rec_while_any_trial_records_and_space_pauses(server: str, browser: playwright_api.Browser) -> None:
    sid = _session(server, "TL02")
    for w in _page(browser, server, (1024, 768)):
        page = _open(w, server, sid)
        badge = page.get_by_test_id("header-recording")
        trial = call(server, "GET", f"/api/trials?session_id={sid}")[0]
        expect(badge).to_be_visible()
        expect(badge).to_have_text(f"● REC trial {trial['id']}")
        # another client stops the recording, then starts one: the header follows without a reload
        call(server, "POST", f"/api/sessions/{sid}/recording", {"action": "stop"})
        expect(badge).to_be_hidden(timeout=10_000)
        expect(page.get_by_test_id("live-recording")).to_have_text("Not recording")
        second = call(server, "POST", f"/api/sessions/{sid}/recording", {"action": "start", "name": "ramp"})
        expect(badge).to_have_text(f"● REC trial {second['id']}", timeout=10_000)
        assert _inside(badge.bounding_box(), 1024, 768)

        # Space pauses and resumes the live plots ...
        page.locator("main").click(position={"x": 5, "y": 5})
        assert not _paused(page)
        page.keyboard.press("Space")
        expect(page.get_by_test_id("live-pause")).to_have_text("Resume")
        expect(page.get_by_test_id("plot-torque").get_by_test_id("plot-state")).to_have_text("paused")
        page.keyboard.press("Space")
        expect(page.get_by_test_id("live-pause")).to_have_text("Pause")
        # ... but not while typing in a field
        page.get_by_test_id("annotation-text").fill("subject ")
        page.get_by_test_id("annotation-text").press("Space")
        assert not _paused(page)
        expect(page.get_by_test_id("annotation-text")).to_have_value("subject  ")
        # leaving the page: the header forgets the session's recording
        page.goto(f"{server}/#/", wait_until="domcontentloaded")
        expect(badge).to_be_hidden()
        w.check_clean()


# --- point 5: plots you can read ---------------------------------------------------------------------------
def test_hover_moves_nothing_and_a_plot_enlarges(server: str, browser: playwright_api.Browser) -> None:
    sid = _session(server, "TL03")
    for w in _page(browser, server, (1440, 900)):
        page = _open(w, server, sid)
        page.mouse.move(2, 890)
        page.wait_for_timeout(300)
        parts = ".key-plots .plot, .key-plots .plot-head, .key-plots .u-over, .key-plots .u-legend"
        before = _boxes(page, parts)
        over = page.get_by_test_id("plot-phase").locator(".u-over").bounding_box()
        assert over
        for fx in (0.2, 0.5, 0.9):  # hover values appear in every linked legend (the phase's has four series)
            page.mouse.move(over["x"] + fx * over["width"], over["y"] + over["height"] / 2)
            value = page.get_by_test_id("plot-torque").locator(".u-legend .u-series").nth(1).locator(".u-value")
            expect(value).to_have_text(re.compile(r"^-?\d+\.\d+$"))
            assert _boxes(page, parts) == before

        # the incline fits its data (a +5 deg treadmill) within at least 4 deg, not a fixed +-15 deg with one tick
        incline = page.get_by_test_id("plot-incline")
        expect(incline).to_have_attribute("data-y-range", re.compile(r"^-?[\d.]+,-?[\d.]+$"))
        lo, hi = (float(v) for v in str(incline.get_attribute("data-y-range")).split(","))
        assert 4 <= hi - lo < 10, (lo, hi)  # the simulated walker ramps up to the slope: the data move within it
        expect(page.get_by_test_id("summary-incline")).to_have_text(re.compile(r"^-?\d+\.\d$"))
        assert lo <= float(page.get_by_test_id("summary-incline").inner_text()) <= hi

        # large-plot mode: the torque plot fills the window, Esc brings it back where it was
        torque = page.get_by_test_id("plot-torque")
        small = torque.bounding_box()
        assert small
        torque.get_by_test_id("plot-enlarge").click()
        expect(torque).to_have_class(re.compile(r"\bgs-large\b"))
        page.wait_for_function(
            "() => document.querySelector('[data-testid=plot-torque] .u-over').getBoundingClientRect().height > 600"
        )
        large = torque.locator(".u-over").bounding_box()
        assert large and large["width"] > 1300
        page.screenshot(path=str(ARTIFACTS / "trust-layout-large-1440.png"))
        page.keyboard.press("Escape")
        expect(torque).not_to_have_class(re.compile(r"\bgs-large\b"))
        page.wait_for_function(
            "() => document.querySelector('[data-testid=plot-torque] .u-over').getBoundingClientRect().height < 300"
        )
        assert torque.bounding_box() == small
        w.check_clean()


def test_named_layout_survives_a_reload_and_goes_out_and_in_as_json(
    server: str, browser: playwright_api.Browser, tmp_path: Path
) -> None:
    sid = _session(server, "TL04")
    for w in _page(browser, server, (1440, 900)):
        page = _open(w, server, sid)
        order = lambda page=page: page.evaluate(  # noqa: E731
            "() => [...document.querySelectorAll('[data-testid=live-panels] > .panel')]"
            ".filter((p) => getComputedStyle(p).display !== 'none').sort((a, b) => a.style.order - b.style.order)"
            ".map((p) => p.dataset.panel)"
        )
        standard = order()
        page.get_by_test_id("layout-menu").locator("summary").click()
        page.get_by_test_id("layout-up-events").click()
        page.get_by_test_id("layout-show-leg").uncheck()
        page.get_by_test_id("layout-size-key-plots").select_option("3")
        mine = order()
        assert mine != standard and "leg" not in mine
        page.get_by_test_id("layout-name").fill("treadmill")
        page.get_by_test_id("layout-save").click()
        expect(page.get_by_test_id("layout-note")).to_have_text("Saved as “treadmill”.")
        with page.expect_download() as dl:
            page.get_by_test_id("layout-export").click()
        exported = tmp_path / "layout.json"
        dl.value.save_as(exported)
        data = json.loads(exported.read_text())
        assert data["format"] == "gaitscope.live.layout/1" and data["name"] == "treadmill"
        assert data["hidden"] == ["leg"] and data["size"]["key-plots"] == 3

        # back to the standard layout, then the saved one after a reload
        page.get_by_test_id("layout-reset").click()
        assert order() == standard
        page.reload(wait_until="domcontentloaded")
        expect(page.get_by_test_id("connection")).to_have_text("connected", timeout=40_000)
        page.get_by_test_id("layout-menu").locator("summary").click()
        expect(page.get_by_test_id("layout-saved")).to_have_value("treadmill")
        page.get_by_test_id("layout-use").click()
        assert order() == mine
        expect(page.locator("[data-panel=key-plots]")).to_have_attribute("data-size", "3")

        # a colleague's file comes in (another name), and a file that is not a layout is refused in words
        data["name"] = "clinic"
        data["hidden"] = []
        other = tmp_path / "clinic.json"
        other.write_text(json.dumps(data))
        page.get_by_test_id("layout-import").set_input_files(str(other))
        expect(page.get_by_test_id("layout-note")).to_have_text("Imported “clinic”.")
        assert "leg" in order()
        bad = tmp_path / "bad.json"
        bad.write_text('{"order": 3}')
        page.get_by_test_id("layout-import").set_input_files(str(bad))
        expect(page.get_by_test_id("layout-note")).to_contain_text("is not a gaitscope live layout")
        assert sorted(page.evaluate(
            "() => [...document.querySelectorAll('[data-testid=layout-saved] option')].map((o) => o.value)"
        )) == ["clinic", "treadmill"]  # fmt: skip
        page.screenshot(path=str(ARTIFACTS / "trust-layout-menu-1440.png"))
        w.check_clean()


def test_screenshots_of_the_review_at_three_sizes(server: str, browser: playwright_api.Browser) -> None:
    sid = _session(server, "TL05")
    trial = call(server, "GET", f"/api/trials?session_id={sid}")[0]
    for w in _page(browser, server, (1024, 768)):  # a few seconds recorded, then the trial ends
        page = _open(w, server, sid, fresh=False)
        page.wait_for_function(
            "() => Number(document.querySelector('[data-testid=health-samples]')?.textContent) >= 600", timeout=30_000
        )
    call(server, "POST", f"/api/sessions/{sid}/recording", {"action": "stop"})
    for width, height in SIZES:
        for w in _page(browser, server, (width, height)):
            page = w.page
            page.goto(f"{server}/#/trials/{trial['id']}", wait_until="domcontentloaded")
            plot = page.get_by_test_id("review-plot-torque")
            expect(plot.locator(".u-over")).to_be_visible()
            assert page.evaluate("() => document.documentElement.scrollWidth") <= width
            if width >= 1024:
                assert _data_share(page, "review-plot-torque") >= 0.6
            page.screenshot(path=str(ARTIFACTS / f"trust-layout-review-{width}.png"))
            w.check_clean()
