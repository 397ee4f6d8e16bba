"""The live view a clinician can read (issue #12, section 2, and the live page's part of section 3).

In Debian chromium against the real server: the key plots in view without scrolling at 1440x900, panels
remembered per acting user, the stop control and data health first on a phone; the last 30 s on opening;
pause and resume while data keeps arriving, zoom of the paused view, hover values in every linked plot; the
setting changes and annotations as labelled markers, the events in plain words; undo, the confirmation before
raising the torque, the applied value beside the edited one and a slider over the absolute range; the
health box amber and red past its limits while the socket is open, LIVE only within them; and after a server
restart the page reconnects by itself, says what happened to the session and starts a new one like it.
Screenshots: ``tests/e2e/artifacts/live-*.png``.
"""

from __future__ import annotations

import json
import re
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO

import pytest
from playwright import sync_api as playwright_api
from websockets.sync.connection import Connection

from gaitscope.server.bench.launch import RunningServer, free_port, start_server
from tests.e2e.accounts import AUTH_ENV, add_users, call, log_in
from tests.e2e.devices import StreamingDevice, device_session
from tests.e2e.pages import ARTIFACTS, Watched, watch
from tests.e2e.servers import serve
from tests.waiting import wait_until

expect = playwright_api.expect

KEY_PLOTS = ("plot-phase", "plot-torque", "plot-phase_rate", "plot-incline")
SIM = {"kind": "simulated", "protocol": [{"speed_m_s": 1.2, "incline_deg": 0.0, "strides": 400}], "rate_hz": 200}


@dataclass
class LiveServer:
    """The module's server, restartable on its port (the restart test)."""

    server: RunningServer
    data: Path
    log: IO[bytes]

    @property
    def base(self) -> str:
        return self.server.base


@pytest.fixture(scope="module")
def live_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LiveServer]:
    data = tmp_path_factory.mktemp("gaitscope-live")
    add_users(data)
    with (data / "server.log").open("ab") as log:
        try:
            running = start_server(data, "--viser-port", str(free_port()), env=AUTH_ENV, output=log)
        except RuntimeError as e:
            pytest.fail(f"{e}:\n{(data / 'server.log').read_text()[-3000:]}")
        live = LiveServer(running, data, log)
        try:
            yield live
        finally:
            live.server.stop()


@pytest.fixture(scope="module")
def server(live_server: LiveServer) -> str:
    return live_server.base


def _page(browser: playwright_api.Browser, width: int, height: int, base: str) -> Iterator[Watched]:
    """A page of this size, logged in as the clinician."""
    context, w = watch(browser, base, viewport=(width, height), timeout_ms=20_000)
    try:
        yield w
    finally:
        context.close()


@pytest.fixture
def wide(browser: playwright_api.Browser, server: str) -> Iterator[Watched]:
    yield from _page(browser, 1440, 900, server)


_STARTED: list[tuple[str, int]] = []  # the sessions a test started, stopped after it (a lighter machine)


@pytest.fixture(autouse=True)
def _stop_sessions() -> Iterator[None]:
    yield
    while _STARTED:
        base, sid = _STARTED.pop()
        try:
            if call(base, "GET", f"/api/sessions/{sid}")["state"] == "running":
                call(base, "POST", f"/api/sessions/{sid}/stop")
        except (AssertionError, OSError):
            pass  # the server is gone (the restart test) or the session ended meanwhile


def _sim_session(server: str, code: str) -> int:
    subject = call(server, "POST", "/api/subjects", {"code": code, "leg_length_m": 0.9, "mass_kg": 70.0})
    session = call(server, "POST", "/api/sessions", {"subject_id": subject["id"], "source": SIM})
    _STARTED.append((server, int(session["id"])))
    return int(session["id"])


def _open(w: Watched, server: str, session_id: int) -> playwright_api.Page:
    page = w.page
    page.goto(f"{server}/#/sessions/{session_id}", wait_until="domcontentloaded")
    expect(page.get_by_test_id("live-title")).to_contain_text(f"Session {session_id}")
    expect(page.get_by_test_id("connection")).to_have_text("connected")
    return page


def _inside(box: dict[str, float] | None, width: int, height: int) -> bool:
    return (
        box is not None
        and box["x"] >= 0
        and box["y"] >= 0
        and box["x"] + box["width"] <= width
        and (box["y"] + box["height"] <= height)
    )


def _canvas(page: playwright_api.Page, testid: str) -> str:
    return str(page.evaluate(f"() => document.querySelector('[data-testid={testid}] canvas').toDataURL()"))


# --- 1. layout -------------------------------------------------------------------------------------------
def test_key_plots_in_view_and_the_layout_is_each_users(server: str, wide: Watched) -> None:
    sid = _sim_session(server, "LAY1")
    page = _open(wide, server, sid)
    page.evaluate("() => localStorage.clear()")
    page.reload(wait_until="domcontentloaded")
    expect(page.get_by_test_id("live-indicator")).to_have_text("LIVE", timeout=20_000)
    for testid in KEY_PLOTS:  # at 1440x900, without scrolling
        box = page.get_by_test_id(testid).bounding_box()
        assert _inside(box, 1440, 900), (testid, box)
    assert page.evaluate("() => window.scrollY") == 0
    page.screenshot(path=str(ARTIFACTS / "live-1440.png"))

    # the clinician moves the events up front and hides the leg view: kept for the clinician, not for others
    panels = page.get_by_test_id("live-panels")
    order = lambda: page.evaluate(  # noqa: E731
        "() => [...document.querySelectorAll('[data-testid=live-panels] > .panel')]"
        ".filter((p) => getComputedStyle(p).display !== 'none').sort((a, b) => a.style.order - b.style.order)"
        ".map((p) => p.dataset.panel)"
    )
    standard = order()
    # (the summary and the session's Stop are not panels since issue #23: the status strip above keeps them in view)
    assert standard[:2] == ["key-plots", "health"] and "leg" in standard
    page.get_by_test_id("layout-menu").locator("summary").click()
    expect(page.get_by_test_id("layout-owner")).to_contain_text("clinician")
    for _ in range(standard.index("events") - 1):
        page.get_by_test_id("layout-up-events").click()
    page.get_by_test_id("layout-show-leg").uncheck()
    page.get_by_test_id("layout-size-events").select_option("2")
    mine = order()
    assert mine[:2] == ["key-plots", "events"] and "leg" not in mine
    expect(panels.locator("[data-panel=events]")).to_have_attribute("data-size", "2")
    page.reload(wait_until="domcontentloaded")
    expect(page.get_by_test_id("connection")).to_have_text("connected")
    assert order() == mine
    for user, layout in (("experimenter", standard), ("clinician", mine)):
        # the experimenter logs in on this browser: the standard layout; the clinician again: hers is back
        log_in(page.context, server, user)
        page.reload(wait_until="domcontentloaded")
        expect(page.get_by_test_id("connection")).to_have_text("connected")
        assert order() == layout, user
    page.get_by_test_id("layout-menu").locator("summary").click()
    page.get_by_test_id("layout-reset").click()
    assert order() == standard
    wide.check_clean()


def test_tablet_and_phone_put_what_matters_first(server: str, browser: playwright_api.Browser) -> None:
    sid = _sim_session(server, "LAY2")
    for width, height in ((1024, 768), (390, 844)):
        for w in _page(browser, width, height, server):
            page = _open(w, server, sid)
            page.evaluate("() => localStorage.clear()")
            page.reload(wait_until="domcontentloaded")
            expect(page.get_by_test_id("live-indicator")).not_to_have_text("NO DATA", timeout=20_000)
            assert page.evaluate("() => document.documentElement.scrollWidth") <= width  # nothing runs off sideways
            stop = page.get_by_test_id("session-stop").bounding_box()
            health = page.get_by_test_id("health").bounding_box()
            phase = page.get_by_test_id("plot-phase").bounding_box()
            events = page.get_by_test_id("events-card").bounding_box()
            assert stop and health and phase and events
            if width == 390:  # a phone: the stop control and the data health come first, in the first screen
                indicator = page.get_by_test_id("live-indicator").bounding_box()  # the health's verdict (issue #23)
                assert indicator and stop["y"] + stop["height"] <= height and indicator["y"] < height
                assert stop["y"] < phase["y"] and health["y"] < phase["y"]
                summary = page.get_by_test_id("summary").bounding_box()
                assert summary and indicator["y"] < summary["y"]
            else:
                assert _inside(page.get_by_test_id("plot-phase").bounding_box(), width, height)
            # the events list fits its panel at every size: no sideways scrolling inside it
            assert page.evaluate(
                "() => { const s = document.querySelector('[data-testid=events-card] .events-scroll');"
                " return s.scrollWidth <= s.clientWidth + 1; }"
            )
            page.screenshot(path=str(ARTIFACTS / f"live-{width}.png"), full_page=width == 390)
            w.check_clean()


# --- 2. history, pause, zoom, hover ----------------------------------------------------------------------
def test_history_on_opening_pause_zoom_and_linked_hover(server: str, wide: Watched) -> None:
    sid = _sim_session(server, "HIS1")
    page = _open(wide, server, sid)
    # the session runs on while this page watches: 7 s of it (200 Hz)
    page.wait_for_function(
        "() => Number(document.querySelector('[data-testid=health-samples]')?.textContent) >= 1400", timeout=30_000
    )
    page.reload(wait_until="domcontentloaded")  # a newly connected browser: the last seconds come first
    t0 = time.monotonic()
    keys = page.locator(".key-plots")
    expect(keys).to_have_attribute("data-shown-s", re.compile(r"^(6|7|8|9|10)\.\d$"), timeout=5_500)
    # over 6 s of data shown sooner than 6 s after opening: they came from the server's history
    assert time.monotonic() - t0 < 6

    # pause: the plots hold still while the data keeps arriving; the paused view zooms; resume catches up
    expect(page.get_by_test_id("live-indicator")).to_have_text("LIVE", timeout=20_000)
    page.get_by_test_id("live-pause").click()
    expect(page.get_by_test_id("live-pause")).to_have_text("Resume")
    expect(page.get_by_test_id("plot-torque").get_by_test_id("plot-state")).to_have_text("paused")
    frozen = _canvas(page, "plot-torque")
    expect(page.get_by_test_id("health-samples")).to_have_text(re.compile(r"^\d+$"))  # a health message came
    samples = int(page.get_by_test_id("health-samples").inner_text())
    page.wait_for_function(  # the data keeps arriving: 1.5 s more of it (200 Hz)
        f"() => Number(document.querySelector('[data-testid=health-samples]').textContent) > {samples + 300}",
        timeout=10_000,
    )
    assert _canvas(page, "plot-torque") == frozen
    page.get_by_test_id("plot-torque").get_by_test_id("plot-zoom-in").click()
    for testid in KEY_PLOTS:  # one zoom for every linked plot
        expect(page.get_by_test_id(testid).get_by_test_id("plot-state")).to_have_text("paused, zoomed")
    assert _canvas(page, "plot-torque") != frozen

    # hover values: the cursor over one plot shows each plot's value at that time, with its unit
    over = page.get_by_test_id("plot-phase_rate").locator(".u-over")
    box = over.bounding_box()
    assert box
    page.mouse.move(box["x"] + box["width"] * 0.6, box["y"] + box["height"] / 2, steps=4)
    torque_value = page.get_by_test_id("plot-torque").locator(".u-legend .u-series").nth(1).locator(".u-value")
    expect(torque_value).to_have_text(re.compile(r"^-?\d+\.\d+$"))
    assert torque_value.get_attribute("data-unit") == "N·m"
    incline_value = page.get_by_test_id("plot-incline").locator(".u-legend .u-series").nth(1).locator(".u-value")
    expect(incline_value).to_have_text(re.compile(r"^-?\d+\.\d+$"))
    page.screenshot(path=str(ARTIFACTS / "live-paused-zoomed.png"))

    page.get_by_test_id("live-pause").click()
    expect(page.get_by_test_id("live-pause")).to_have_text("Pause")
    expect(page.get_by_test_id("plot-torque").get_by_test_id("plot-state")).to_have_text("")
    wait_until(lambda: _canvas(page, "plot-torque") != frozen, 5.0, "the resumed plot to move")
    wide.check_clean()


# --- 3 and 4. markers, events in plain words, undo, confirmation, applied value, rate-limited slider -------
def test_changes_as_markers_undo_and_safe_controls(server: str, wide: Watched) -> None:
    sid = _sim_session(server, "SET1")
    page = _open(wide, server, sid)
    wide.allow_refusal(409, rf"/api/sessions/{sid}/settings/undo$")
    expect(page.get_by_test_id("setting-torque_gain-applied")).to_have_text("applied now: 1.00")
    undo = page.get_by_test_id("settings-undo")
    expect(undo).to_be_disabled()
    expect(page.get_by_test_id("settings-undo-what")).to_have_text("No change to undo yet.")

    # the slider spans the gain's whole range; its rate limit is said beside it (issue #23, 6)
    slider = page.get_by_test_id("setting-torque_gain-slider")
    expect(slider).to_have_attribute("max", "3")
    expect(slider).to_have_attribute("min", "0")
    rate = page.get_by_test_id("setting-torque_gain-rate")
    expect(rate).to_have_text("up to ±0.5 per change; lowering: any step, at any time")
    page.get_by_test_id("setting-torque_gain").fill("1.3")
    expect(page.get_by_test_id("setting-torque_gain-applied")).to_have_text("applied now: 1.00")  # beside the edit
    page.get_by_test_id("settings-apply").click()
    page.get_by_test_id("confirm-raise").click()  # a raise asks first (tests/e2e/test_trust_confirm.py)
    expect(page.get_by_test_id("settings-ok")).to_have_text("Applied: Torque gain.")
    expect(page.get_by_test_id("setting-torque_gain-applied")).to_have_text("applied now: 1.30")
    # just changed, the rate limit says how soon the full step comes back; a second later, the full step again
    expect(rate).to_have_text("up to ±0.5 per change; lowering: any step, at any time", timeout=3_000)
    expect(slider).to_have_attribute("max", "3")  # never narrowed
    slider.fill("3")  # dragged to the end: the slider goes there
    expect(page.get_by_test_id("setting-torque_gain")).to_have_value("3")
    page.get_by_test_id("settings-revert").click()

    # the change in the events list, in plain words, and as a labelled marker on every time plot
    row = page.get_by_test_id("event-row").and_(page.locator("[data-kind=setting]"))
    expect(row.get_by_test_id("event-text")).to_have_text("Torque gain 1.00 → 1.30, by clinician")
    expect(page.get_by_test_id("events-list")).not_to_contain_text("torque_gain")
    expect(page.get_by_test_id("settings-undo-what")).to_have_text(
        "Last change: Torque gain 1.00 → 1.30, by clinician."
    )
    page.get_by_test_id("annotation-text").fill("subject reports discomfort")
    page.get_by_test_id("annotation-add").click()
    note = page.get_by_test_id("event-row").and_(page.locator("[data-kind=annotation]"))
    expect(note.get_by_test_id("event-text")).to_have_text("subject reports discomfort")
    expect(note.get_by_test_id("event-actor")).to_have_text("by clinician")
    page.evaluate("() => window.scrollTo(0, 0)")  # the key plots in view again (off screen, plots do not draw)
    for testid in KEY_PLOTS:
        expect(page.get_by_test_id(testid)).to_have_attribute("data-markers", re.compile(r"Torque gain 1\.00 → 1\.30"))
        expect(page.get_by_test_id(testid)).to_have_attribute(
            "data-markers", re.compile(r"Note: subject reports discomfort")
        )
    marks = json.loads(page.get_by_test_id("plot-torque").get_attribute("data-markers") or "[]")
    label, x, _ = next(m for m in marks if m[0].startswith("Torque gain"))
    over = page.get_by_test_id("plot-torque").locator(".u-over").bounding_box()
    assert over
    page.get_by_test_id("live-pause").click()  # hold the marker still to hover it
    page.wait_for_timeout(600)  # (the page notes where markers are drawn five times a second)
    marks = json.loads(page.get_by_test_id("plot-torque").get_attribute("data-markers") or "[]")
    label, x, _ = next(m for m in marks if m[0].startswith("Torque gain"))
    page.mouse.move(over["x"] + x, over["y"] + over["height"] / 2, steps=3)
    expect(page.get_by_test_id("plot-torque").get_by_test_id("plot-marker-tip")).to_contain_text(label)
    page.screenshot(path=str(ARTIFACTS / "live-markers.png"))
    page.get_by_test_id("live-pause").click()

    # undo, in one action, itself logged
    expect(undo).to_be_enabled()
    undo.click()
    expect(page.get_by_test_id("settings-ok")).to_contain_text("Undone")
    expect(page.get_by_test_id("setting-torque_gain-applied")).to_have_text("applied now: 1.00")
    expect(row.first.get_by_test_id("event-text")).to_have_text(
        "Torque gain 1.30 → 1.00 (undo of the previous change), by clinician"
    )
    assert call(server, "GET", f"/api/sessions/{sid}")["settings"]["torque_gain"] == 1.0

    # raising the maximum torque asks first; cancelling leaves it; lowering does not ask, nor wait
    page.get_by_test_id("setting-max_torque_Nm").fill("35")
    page.get_by_test_id("settings-apply").click()
    expect(page.get_by_test_id("confirm-raise-text")).to_have_text(
        re.compile(r"^Change maximum torque 30\.0 → 35\.0\? This can raise the torque on the person")
    )
    page.get_by_test_id("confirm-raise-cancel").click()
    expect(page.get_by_test_id("confirm-raise-box")).to_be_hidden()
    assert call(server, "GET", f"/api/sessions/{sid}")["settings"]["max_torque_Nm"] == 30.0
    page.get_by_test_id("settings-apply").click()
    page.get_by_test_id("confirm-raise").click()
    expect(page.get_by_test_id("setting-max_torque_Nm-applied")).to_have_text("applied now: 35.0")
    page.get_by_test_id("setting-max_torque_Nm").fill("32")
    page.get_by_test_id("settings-apply").click()
    expect(page.get_by_test_id("setting-max_torque_Nm-applied")).to_have_text("applied now: 32.0")
    expect(page.get_by_test_id("confirm-raise-box")).to_be_hidden()
    wide.check_clean()


# --- 5. the health box judges the figures, whatever the socket's state --------------------------------------
class LateDevice(StreamingDevice):
    """A 100 Hz device whose frames reach the server ``late_ms`` after they were stamped."""

    late_ms = 0.0

    def stream(self, ws: Connection) -> None:
        seq = 0
        start = time.monotonic()
        while not self.stop.is_set():
            sent = time.time_ns() - int(self.late_ms * 1e6)
            frame = {"seq": seq, "t": seq / 100, "sent_ns": sent, "foot_angle_deg": 0.0, "shank_angle_deg": 0.0}
            ws.send(json.dumps(frame))
            ws.recv(timeout=5)
            seq += 1
            self.pace(start, seq, 100.0)  # 100 Hz, as declared


class AmberDevice(LateDevice):
    late_ms = 450.0


class RedDevice(LateDevice):
    late_ms = 1500.0


def test_health_box_turns_amber_and_red_past_its_limits(server: str, wide: Watched) -> None:
    page = wide.page
    for device, level, text in ((AmberDevice, "amber", "CHECK DATA"), (RedDevice, "red", "NOT LIVE")):
        code = f"HL{level[0].upper()}"
        with device_session(server, code, 100.0, ["foot_angle_deg", "shank_angle_deg"], device) as (sid, _):
            page.goto(f"{server}/#/sessions/{sid}", wait_until="domcontentloaded")
            expect(page.get_by_test_id("connection")).to_have_text("connected")  # the socket is fine ...
            health = page.get_by_test_id("health")
            expect(health).to_have_attribute("data-level", level, timeout=15_000)  # ... the data is not
            expect(page.get_by_test_id("live-indicator")).to_have_text(text)
            expect(page.get_by_test_id("health-reasons")).to_contain_text(
                "Device → screen delay (95th percentile)" if level == "amber" else "over the red limit of 1000 ms"
            )
            page.get_by_test_id("health-help").locator("summary").click()
            expect(page.get_by_test_id("health-help")).to_contain_text(
                "Device → screen delay (95th percentile): amber from 200 ms, red from 1000 ms."
            )
            page.screenshot(path=str(ARTIFACTS / f"live-health-{level}.png"))
    wide.check_clean()


# --- 6. a server restart: the page reconnects by itself and says what happened -----------------------------
def test_after_a_restart_the_page_says_what_happened_and_starts_a_new_session(
    live_server: LiveServer, wide: Watched
) -> None:
    base = live_server.base
    sid = _sim_session(base, "RST1")
    call(base, "PATCH", f"/api/sessions/{sid}/settings", {"torque_gain": 1.2, "confirm": True})
    page = _open(wide, base, sid)
    expect(page.get_by_test_id("live-indicator")).to_have_text("LIVE", timeout=20_000)
    old = live_server.server
    old.stop()
    expect(page.get_by_test_id("live-indicator")).to_have_text("NOT LIVE", timeout=5_000)
    expect(page.get_by_test_id("health-reasons")).to_contain_text("No connection to the server.")
    live_server.server = serve(live_server.data, old.port, live_server.log, "--viser-port", str(free_port()))
    ended = page.get_by_test_id("session-ended")
    expect(ended).to_be_visible(timeout=30_000)  # reconnected by itself (no reload), and found the session stopped
    expect(page.get_by_test_id("session-ended-text")).to_have_text(
        re.compile(
            r"^This session was stopped (by a server restart|when the server restarted) at \d\d:\d\d:\d\d( [AP]M)?\.$"
        )
    )
    page.screenshot(path=str(ARTIFACTS / "live-after-restart.png"))
    expect(page.get_by_test_id("session-summary-link")).to_have_attribute("href", f"#/sessions/{sid}/summary")
    page.get_by_test_id("session-restart").click()
    expect(page).not_to_have_url(re.compile(rf"#/sessions/{sid}$"))  # the new session's page
    new_id = int(re.search(r"#/sessions/(\d+)$", page.url)[1])  # type: ignore[index]
    assert new_id != sid
    expect(page.get_by_test_id("live-indicator")).to_have_text("LIVE", timeout=30_000)
    before, after = call(base, "GET", f"/api/sessions/{sid}"), call(base, "GET", f"/api/sessions/{new_id}")
    assert after["subject_id"] == before["subject_id"] and after["source"] == before["source"]
    assert after["settings"] == before["settings"] and after["settings"]["torque_gain"] == 1.2
    assert after["state"] == "running"
    _STARTED.append((base, new_id))
    # the lost connection logs failed requests while the server is down: those are expected, nothing else
    wide.console_errors = [e for e in wide.console_errors if "ERR_CONNECTION_REFUSED" not in e and "WebSocket" not in e]
    wide.check_clean()
