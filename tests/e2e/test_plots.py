"""The plot component (``web/plots.js``) in a real browser against the real server (issue #12).

Two parts. First, a group of three live-following plots built from ``/plots.js`` itself on a page of the
dashboard, fed 200 samples/s by the page (a ring buffer, as the live view's): drag-zoom, wheel zoom, pan
(Shift+drag and pan mode), double-click reset move every linked plot together; the cursor and the hover
values (with units) follow in every plot; labelled markers are drawn (line colour on the canvas, label row,
hover text); y ranges come from the table (the torque's from the session's bound), are adjustable, refused
in plain words when wrong and remembered across a reload; pause freezes what is drawn while the data keeps
coming and resume catches up. Second, the live view and review as they are today with a device streaming
at 200 Hz: hover values with units, a zoom, and the browser-side frame rate of the live page with all its
panels (written to ``tests/e2e/artifacts/plots-fps.json``; ``docs/dashboard.md`` quotes it).
Screenshots: ``tests/e2e/artifacts/plots-*.png`` at 1440x900, 1024x768 and 390x844.
The fixtures are ``conftest.py``'s (this module gets its own server).
"""

from __future__ import annotations

import functools
import json
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import pytest
from websockets.sync.connection import Connection

from tests.e2e.accounts import record
from tests.e2e.devices import StreamingDevice, device_session
from tests.e2e.pages import ARTIFACTS, Watched, wait_responsive

if TYPE_CHECKING:
    from playwright.sync_api import FloatRect, Locator, Page

playwright_api = pytest.importorskip("playwright.sync_api")
expect = playwright_api.expect


VIEWPORTS = [(1440, 900), (1024, 768), (390, 844)]
RATE = 200.0  # Hz: the device's and the harness's sample rate
CHANNELS = ["foot_angle_deg", "foot_vel_dps", "shank_angle_deg", "shank_vel_dps", "thigh_angle_deg", "thigh_vel_dps",
            "heel_strike"]  # fmt: skip
UNITS = {"phase": "%", "torque": "N·m", "incline": "deg"}

# Three linked plots following the newest 10 s of a ring of 12 s fed 200 samples/s: phase, torque, incline (the
# incline a 0.1 deg ripple, which auto-scaling would blow up to fill the plot).
HARNESS = """async () => {
  const P = await import("/plots.js");
  document.getElementById("view").hidden = true;
  const box = document.createElement("div");
  box.id = "harness";
  box.style.cssText = "padding: 8px";
  document.body.append(box);
  const group = new P.PlotGroup({ pauseOnZoom: true });
  const ring = new P.Ring(2400, ["t", "phase_pct", "torque_Nm", "incline_deg"]);
  const follow = (u, min, max) => (max == null ? [0, 10] : [max - 10, max]);
  const spec = (key, title, yLabel, col, label, color) =>
    ({ key, title, yLabel, cols: [col], series: [{ label, color }] });
  const specs = [
    spec("phase", "Gait phase", "% of cycle", "phase_pct", "phase", P.COLORS.blue),
    spec("torque", "Torque command", "N·m", "torque_Nm", "torque", P.COLORS.orange),
    spec("incline", "Incline", "deg", "incline_deg", "incline", P.COLORS.green),
  ];
  const plots = specs.map((spec) => {
    const div = document.createElement("div");
    div.className = "plot";
    div.dataset.testid = `h-${spec.key}`;
    box.append(div);
    return { spec, plot: new P.Plot(div, { ...spec, xRange: follow, group, height: 200 }) };
  });
  const t0 = performance.now();
  let n = 0;
  const timer = setInterval(() => {
    const now = (performance.now() - t0) / 1000;
    for (; n / 200 <= now; n++) {
      const t = n / 200;
      ring.push({ t, phase_pct: ((t % 1.1) / 1.1) * 100, torque_Nm: 20 * Math.max(0, Math.sin((2 * Math.PI * t) / 1.1)),
        incline_deg: 0.1 * Math.sin(t) });
    }
  }, 10);
  const frame = () => {
    window.__h.raf = requestAnimationFrame(frame);
    for (const p of plots) p.plot.setData(ring.window("t", p.spec.cols, 10));
  };
  window.__h = { P, group, ring, plots: plots.map((p) => p.plot), timer, raf: requestAnimationFrame(frame) };
}"""


def _harness(page: Page, server: str) -> None:
    page.goto("about:blank")  # a new document each time (a hash-only navigation would keep the old one)
    page.goto(f"{server}/#/")
    page.evaluate(HARNESS)
    page.wait_for_function("() => window.__h.ring.last('t') > 12")  # more than one 10 s window of data


def _xs(page: Page) -> list[list[float]]:
    """Every harness plot's x range [min, max]."""
    xs: list[list[float]] = page.evaluate("() => __h.plots.map((p) => [p.u.scales.x.min, p.u.scales.x.max])")
    return xs


def _ys(page: Page) -> list[list[float]]:
    """Every harness plot's y range [min, max]."""
    ys: list[list[float]] = page.evaluate("() => __h.plots.map((p) => [p.u.scales.y.min, p.u.scales.y.max])")
    return ys


def _over(page: Page, key: str) -> FloatRect:
    box = page.get_by_test_id(f"h-{key}").locator(".u-over").bounding_box()
    assert box is not None, f"the {key} plot has no drawing area"
    return box


def _at(box: FloatRect, fx: float, fy: float = 0.5) -> tuple[float, float]:
    return box["x"] + fx * box["width"], box["y"] + fy * box["height"]


def _drag(page: Page, a: tuple[float, float], b: tuple[float, float], shift: bool = False) -> None:
    page.mouse.move(*a)
    if shift:
        page.keyboard.down("Shift")
    page.mouse.down()
    page.mouse.move(*b, steps=6)
    page.mouse.up()
    if shift:
        page.keyboard.up("Shift")


def _linked(xs: list[list[float]]) -> list[float]:
    """The one x range every plot shows (asserting they agree)."""
    for r in xs[1:]:
        assert r == pytest.approx(xs[0], abs=1e-9), xs
    return xs[0]


def _legends(page: Page, testid_prefix: str = "h-") -> dict[str, list[tuple[str, str, str]]]:
    """Per plot (test id without the prefix): its legend rows as (label, value text, unit shown after it)."""
    legends: dict[str, list[tuple[str, str, str]]] = page.evaluate(
        """(prefix) => Object.fromEntries([...document.querySelectorAll(`[data-testid^="${prefix}"]`)]
          .filter((el) => el.querySelector(".u-legend"))
          .map((el) => [el.dataset.testid.slice(prefix.length), [...el.querySelectorAll(".u-legend .u-series")]
            .map((r) => { const v = r.querySelector(".u-value");
              return [r.querySelector(".u-label").textContent, v.textContent,
                getComputedStyle(v, "::after").content]; })]))""",
        testid_prefix,
    )
    return legends


def _hover_rows(
    page: Page, plot: Locator, prefix: str, key: str, frac: float = 0.5, timeout_s: float = 10.0
) -> list[tuple[str, str, str]]:
    """The legend rows of plot ``key`` with the mouse at ``frac`` of its width, once the legend shows a value
    (the legend follows the cursor on the browser's next frame; on a loaded machine that can take a while)."""
    deadline = time.monotonic() + timeout_s
    nudge = 0.0
    while True:
        box = plot.locator(".u-over").bounding_box()
        assert box is not None, "the plot has no drawing area"
        page.mouse.move(*_at(box, frac + nudge))
        page.wait_for_timeout(100)
        rows = _legends(page, prefix)[key]
        if rows[1][1] not in ("–", "") or time.monotonic() > deadline:
            return rows
        nudge = 0.01 if nudge == 0 else 0.0  # a move to the same point is no move: alternate


def test_zoom_pan_reset_linked(server: str, watched: Watched) -> None:
    page = watched.page
    page.set_viewport_size({"width": 1440, "height": 900})
    _harness(page, server)
    before = _linked(_xs(page))
    assert before[1] - before[0] == pytest.approx(10, abs=0.05)  # following the newest 10 s

    # --- drag across 20-60 % of the phase plot: every linked plot shows those 4 s, paused (pauseOnZoom) ------
    box = _over(page, "phase")
    _drag(page, _at(box, 0.2), _at(box, 0.6))
    zoomed = _linked(_xs(page))
    assert zoomed[1] - zoomed[0] == pytest.approx(4.0, abs=0.4), zoomed
    assert page.evaluate("() => __h.group.paused") is True
    expect(page.get_by_test_id("h-torque").get_by_test_id("plot-state")).to_have_text("paused, zoomed")
    page.wait_for_timeout(400)
    assert _linked(_xs(page)) == pytest.approx(zoomed, abs=1e-9)  # data flowing, the paused view still
    page.screenshot(path=str(ARTIFACTS / "plots-zoomed-1440.png"))

    # --- the wheel over the torque plot zooms about the cursor: the time under it stays put ----------------
    box = _over(page, "torque")
    x, y = _at(box, 0.3)
    t_at = zoomed[0] + 0.3 * (zoomed[1] - zoomed[0])
    page.mouse.move(x, y)
    page.mouse.wheel(0, -100)
    page.wait_for_timeout(100)
    w = _linked(_xs(page))
    assert w[1] - w[0] == pytest.approx(0.8 * (zoomed[1] - zoomed[0]), rel=0.02), (zoomed, w)
    assert w[0] + 0.3 * (w[1] - w[0]) == pytest.approx(t_at, abs=0.02)
    page.mouse.wheel(0, 100)  # and back out
    page.wait_for_timeout(100)
    assert _linked(_xs(page)) == pytest.approx(zoomed, abs=0.01)

    # --- Shift+drag pans: 25 % of the width to the right shows a quarter of the span earlier -----------------
    box = _over(page, "incline")
    _drag(page, _at(box, 0.5), _at(box, 0.75), shift=True)
    p = _linked(_xs(page))
    span = zoomed[1] - zoomed[0]
    assert p[0] == pytest.approx(zoomed[0] - 0.25 * span, abs=0.05), (zoomed, p)
    assert p[1] - p[0] == pytest.approx(span, abs=1e-6)
    # pan mode: a plain drag pans too (leftwards: later)
    pan = page.get_by_test_id("h-phase").get_by_test_id("plot-pan")
    pan.click()
    # the group's mode: every plot's button says so
    expect(page.get_by_test_id("h-torque").get_by_test_id("plot-pan")).to_have_attribute("aria-pressed", "true")
    box = _over(page, "phase")
    _drag(page, _at(box, 0.75), _at(box, 0.5))
    assert _linked(_xs(page)) == pytest.approx(zoomed, abs=0.05)
    pan.click()
    expect(pan).to_have_attribute("aria-pressed", "false")
    # the toolbar's "+" halves the span about the middle
    page.get_by_test_id("h-torque").get_by_test_id("plot-zoom-in").click()
    z = _linked(_xs(page))
    assert z[1] - z[0] == pytest.approx(span / 2, rel=0.05)
    assert (z[0] + z[1]) / 2 == pytest.approx((zoomed[0] + zoomed[1]) / 2, abs=0.05)

    # "‹" moves a quarter of the view earlier, "›" back
    page.get_by_test_id("h-incline").get_by_test_id("plot-earlier").click()
    e = _linked(_xs(page))
    assert e[0] == pytest.approx(z[0] - (z[1] - z[0]) / 4, abs=1e-6) and e[1] - e[0] == pytest.approx(z[1] - z[0])
    page.get_by_test_id("h-incline").get_by_test_id("plot-later").click()
    assert _linked(_xs(page)) == pytest.approx(z, abs=1e-6)

    # --- double-click: back to the plot's own range (the paused data's newest 10 s) --------------------------
    page.mouse.dblclick(*_at(_over(page, "incline"), 0.5))
    r = _linked(_xs(page))
    assert r[1] - r[0] == pytest.approx(10, abs=0.05)
    assert page.evaluate("() => __h.group.x") is None
    expect(page.get_by_test_id("h-phase").get_by_test_id("plot-reset")).to_be_disabled()
    # resume: the newest data again, following it
    page.evaluate("() => __h.group.resume()")
    page.wait_for_timeout(200)
    r = _linked(_xs(page))
    assert r[1] == pytest.approx(page.evaluate("() => __h.ring.last('t')"), abs=0.25)
    watched.check_clean()


def test_hover_values_with_units_in_every_plot(server: str, watched: Watched) -> None:
    page = watched.page
    for width, height in VIEWPORTS:
        page.set_viewport_size({"width": width, "height": height})
        _harness(page, server)
        page.evaluate("() => __h.group.pause()")  # still data: the values under the cursor are stable
        for key, frac in (("torque", 0.35), ("phase", 0.8)):
            page.get_by_test_id(f"h-{key}").scroll_into_view_if_needed()
            page.mouse.move(*_at(_over(page, key), frac))
            page.wait_for_timeout(60)
            legends = _legends(page)
            assert set(legends) == set(UNITS), legends
            times = {k: float(rows[0][1]) for k, rows in legends.items()}  # the same time in every linked plot
            assert max(times.values()) - min(times.values()) < 0.011, times
            x = _xs(page)[0]
            assert times[key] == pytest.approx(x[0] + frac * (x[1] - x[0]), abs=0.05)
            for k, rows in legends.items():
                _, value, after = rows[1]
                float(value)  # the legend's text is the bare number ...
                assert after == f'" {UNITS[k]}"', (k, rows)  # ... and the unit is shown after it
            # the phase at the cursor is the harness's own signal at that time
            t = times["phase"]
            d = abs(float(legends["phase"][1][1]) - ((t % 1.1) / 1.1) * 100)
            assert min(d, 100 - d) < 2.0, (t, legends["phase"])  # (modulo the wrap from 100 to 0 %)
        page.screenshot(path=str(ARTIFACTS / f"plots-hover-{width}.png"))
    watched.check_clean()


def test_labelled_markers(server: str, watched: Watched) -> None:
    page = watched.page
    page.set_viewport_size({"width": 1024, "height": 768})
    _harness(page, server)
    page.evaluate("() => __h.group.pause()")
    x = _xs(page)[0]
    marks = [
        {"t": x[0] + 3.0, "label": "Torque gain 1.00 -> 1.30, by clinician", "kind": "setting"},
        {"t": x[0] + 3.2, "label": "Note: patient reports fatigue", "kind": "annotation"},  # close: a second row
        {"t": x[0] + 8.0, "label": "Recording started", "kind": "recording", "color": "#ff00ff"},
    ]
    page.evaluate("(m) => __h.group.setMarkers(m)", marks)
    drawn = page.evaluate("() => __h.plots.map((p) => p.drawnMarkers)")
    for per_plot in drawn:
        assert [d["label"] for d in per_plot] == [m["label"] for m in marks]
        assert [d["row"] for d in per_plot] == [0, 1, 0]  # the close pair's labels do not overlap
    # the third marker's line is on the canvas in its colour, in every plot
    pixels = page.evaluate(
        """() => __h.plots.map((p) => { const m = p.drawnMarkers[2]; const pr = devicePixelRatio;
          const x = Math.round(p.u.bbox.left + m.x * pr); const y = Math.round(p.u.bbox.top + p.u.bbox.height * 0.6);
          return [...p.u.ctx.getImageData(x - 1, y, 3, 12).data]; })"""  # 12 rows: across a dash's gap
    )
    for px in pixels:
        assert any(px[i] > 200 and px[i + 1] < 60 and px[i + 2] > 200 for i in range(0, len(px), 4)), px
    # hovering near a line shows its text
    box = _over(page, "torque")
    m0 = drawn[1][0]["x"]
    page.mouse.move(box["x"] + m0 + 2, box["y"] + box["height"] * 0.7)
    tip = page.get_by_test_id("h-torque").get_by_test_id("plot-marker-tip")
    expect(tip).to_be_visible()
    expect(tip).to_contain_text("Torque gain 1.00 -> 1.30, by clinician")
    expect(page.get_by_test_id("h-phase").get_by_test_id("plot-marker-tip")).to_be_hidden()  # only where the mouse is
    page.mouse.move(box["x"] + box["width"] * 0.55, box["y"] + box["height"] * 0.7)
    expect(tip).to_be_hidden()
    page.get_by_test_id("h-phase").scroll_into_view_if_needed()
    page.screenshot(path=str(ARTIFACTS / "plots-markers-1024.png"))
    # a marker without a time is refused, saying which
    err = page.evaluate(
        "() => { try { __h.group.setMarkers([{ t: 1, label: 'a' }, { label: 'b' }]); }"
        " catch (e) { return e.message; } }"
    )
    assert err == "setMarkers: marker 1 has no finite time t"
    watched.check_clean()


def test_y_ranges_fixed_adjustable_remembered(server: str, watched: Watched) -> None:
    page = watched.page
    page.set_viewport_size({"width": 1024, "height": 768})
    _harness(page, server)
    page.evaluate("() => localStorage.clear()")
    page.evaluate("() => __h.plots.forEach((p) => p._applyY())")
    # the table's ranges: phase 0-100 %, torque 0 to the session's bound (30 N·m by default, 5 % headroom),
    # incline fitted to its data but never narrower than 4 deg (issue #23), although it only ripples by 0.1 deg
    assert _ys(page) == [[0, 100], [0, pytest.approx(31.5)], [-2, 2]]
    page.evaluate("() => __h.group.setContext({ max_torque_Nm: 50 })")
    assert _ys(page)[1] == [0, pytest.approx(52.5)]

    incline = page.get_by_test_id("h-incline")
    incline.get_by_test_id("plot-y-range").click()
    form = incline.get_by_test_id("plot-y-form")
    expect(form).to_be_visible()
    expect(incline.get_by_test_id("plot-y-min")).to_have_value("-2")
    incline.get_by_test_id("plot-y-min").fill("5")
    incline.get_by_test_id("plot-y-max").fill("2")
    incline.get_by_test_id("plot-y-apply").click()
    expect(incline.get_by_test_id("plot-y-error")).to_have_text("The lowest value must be below the highest.")
    incline.get_by_test_id("plot-y-max").fill("")
    incline.get_by_test_id("plot-y-apply").click()
    expect(incline.get_by_test_id("plot-y-error")).to_have_text("The highest value must be a number.")
    incline.get_by_test_id("plot-y-min").fill("-0.5")
    incline.get_by_test_id("plot-y-max").fill("0.5")
    incline.get_by_test_id("plot-y-apply").click()
    expect(form).to_be_hidden()
    assert _ys(page)[2] == [-0.5, 0.5]
    expect(incline.get_by_test_id("plot-y-range")).to_have_text("Y -0.5 to 0.5")
    page.screenshot(path=str(ARTIFACTS / "plots-yrange-1024.png"))

    # remembered: a new page's incline plot starts with it
    _harness(page, server)
    assert _ys(page)[2] == [-0.5, 0.5]
    incline = page.get_by_test_id("h-incline")
    incline.get_by_test_id("plot-y-range").click()
    incline.get_by_test_id("plot-y-default").click()
    assert _ys(page)[2] == [-2, 2]
    assert page.evaluate("() => localStorage.getItem('gaitscope.plots.y.incline')") is None
    watched.check_clean()


def test_pause_freezes_then_resume_catches_up(server: str, watched: Watched) -> None:
    page = watched.page
    page.set_viewport_size({"width": 1024, "height": 768})
    _harness(page, server)
    page.evaluate("() => __h.group.pause()")
    frozen = _linked(_xs(page))
    drawn_last = page.evaluate("() => __h.plots.map((p) => p.u.data[0][p.u.data[0].length - 1])")
    n0 = page.evaluate("() => __h.ring.n")
    first = page.evaluate("() => __h.plots.map((p) => [p.u.data[0][0], p.u.data[1][0]])")
    page.wait_for_timeout(1500)
    assert page.evaluate("() => __h.ring.n") - n0 > 200  # data kept coming (200 samples/s) ...
    assert _linked(_xs(page)) == pytest.approx(frozen, abs=1e-9)  # ... the drawing did not move
    assert page.evaluate("() => __h.plots.map((p) => p.u.data[0][p.u.data[0].length - 1])") == drawn_last
    # the frozen data is a copy: 3 s of samples wrapped the 12 s ring over the first ones drawn
    page.wait_for_timeout(1500)
    assert page.evaluate("() => __h.ring.n") - n0 > 400
    assert page.evaluate("() => __h.plots.map((p) => [p.u.data[0][0], p.u.data[1][0]])") == first
    # zoom works on the paused view
    page.evaluate(f"() => __h.group.setX({frozen[0] + 2}, {frozen[0] + 4})")
    assert _linked(_xs(page)) == pytest.approx([frozen[0] + 2, frozen[0] + 4])
    expect(page.get_by_test_id("h-phase").get_by_test_id("plot-state")).to_have_text("paused, zoomed")
    page.screenshot(path=str(ARTIFACTS / "plots-paused-1024.png"))
    # resume: the newest data, following it, zoom gone
    page.evaluate("() => __h.group.resume()")
    page.wait_for_timeout(200)
    r = _linked(_xs(page))
    assert r[1] == pytest.approx(page.evaluate("() => __h.ring.last('t')"), abs=0.25)
    assert r[1] > frozen[1] + 2.5 and r[1] - r[0] == pytest.approx(10, abs=0.05)
    expect(page.get_by_test_id("h-phase").get_by_test_id("plot-state")).to_have_text("")
    watched.check_clean()


# --- the live view and review as they are, a device streaming at 200 Hz ----------------------------------


@functools.cache
def _walk() -> list[dict[str, Any]]:
    from gaitscope.sessions.live.sources import frames_from_table
    from gaitscope.sessions.synth.trials import sensor_trial

    sensors, _, _ = sensor_trial([(1.2, 0.0, 40)], rate_hz=RATE)
    return [{"type": "frame", "t": f.t, **f.model_dump(include=set(CHANNELS))} for f in frames_from_table(sensors)]


class Device(StreamingDevice):
    """Sends the walk at 200 frames/s, over and over (session time running on), each frame answered by a torque;
    ``sent`` counts the frames sent."""

    sent = 0

    def stream(self, ws: Connection) -> None:
        frames = _walk()
        period = len(frames) / RATE
        start = time.monotonic()
        seq = 0
        while not self.stop.is_set():
            frame = frames[seq % len(frames)]
            ws.send(json.dumps({**frame, "t": (seq // len(frames)) * period + frame["t"], "seq": seq}))
            ws.recv(timeout=5)
            seq += 1
            self.sent = seq
            self.pace(start, seq, RATE)


@pytest.fixture
def streaming(server: str) -> Iterator[tuple[int, Device]]:
    with device_session(server, "PLOT1", RATE, CHANNELS, Device) as opened:
        yield opened


def test_live_and_review_plots_at_200_hz(server: str, watched: Watched, streaming: tuple[int, Device]) -> None:
    sid, device = streaming
    page = watched.page
    page.set_viewport_size({"width": 1440, "height": 900})
    page.goto(f"{server}/#/sessions/{sid}")
    expect(page.get_by_test_id("live-indicator")).to_have_text("LIVE", timeout=20_000)
    page.wait_for_timeout(4000)  # plots full of data, strides in the overlay

    # --- the browser's frame rate with every panel of the live page open, at 1440x900 -----------------------
    # every panel open (a fresh browser has the standard layout: none hidden)
    assert page.locator("[data-testid=live-panels] .panel-hidden").count() == 0
    wait_responsive(page)
    sent0, t0 = device.sent, time.monotonic()
    stats = page.evaluate("async () => (await import('/plots.js')).measureFrames(8)")
    rate = (device.sent - sent0) / (time.monotonic() - t0)
    assert rate == pytest.approx(RATE, rel=0.1)  # the device kept streaming at 200 Hz meanwhile
    stats["viewport"] = "1440x900"
    stats["device_rate_hz"] = rate
    stats["health_rate_text"] = page.get_by_test_id("health-rate").inner_text()
    stats["plots_on_page"] = page.locator(".gs-plot").count()
    ARTIFACTS.mkdir(exist_ok=True)
    (ARTIFACTS / "plots-fps.json").write_text(json.dumps(stats, indent=2) + "\n")
    print(f"live page, 200 Hz, 1440x900: {stats}")
    assert stats["frames"] > 0 and stats["fps"] > 20, stats  # a floor for a loaded CI machine; 60 is the aim

    # --- hover values with units in the live plots; a drag zooms a plot, a double-click resets it ----------
    torque = page.get_by_test_id("plot-torque")
    torque.scroll_into_view_if_needed()
    box = torque.locator(".u-over").bounding_box()
    assert box is not None
    rows = _hover_rows(page, torque, "plot-", "torque")
    assert rows[1][0] == "torque" and rows[1][2] == '" N·m"', rows
    float(rows[1][1])
    _drag(page, _at(box, 0.3), _at(box, 0.6))
    expect(torque.get_by_test_id("plot-state")).to_contain_text("zoomed")
    expect(torque.get_by_test_id("plot-reset")).to_be_enabled()
    page.mouse.dblclick(*_at(box, 0.5))
    expect(torque.get_by_test_id("plot-state")).not_to_contain_text("zoomed")  # (a live page may stay paused)
    expect(torque.get_by_test_id("plot-reset")).to_be_disabled()
    for width, height in VIEWPORTS:
        page.set_viewport_size({"width": width, "height": height})
        page.wait_for_timeout(500)
        page.get_by_test_id("plot-phase").scroll_into_view_if_needed()
        page.screenshot(path=str(ARTIFACTS / f"plots-live-{width}.png"))

    # --- review of a recording: units, zoom, reset --------------------------------------------------------
    trial = record(server, sid, 3.0, "plots check")
    page.set_viewport_size({"width": 1440, "height": 900})
    page.goto(f"{server}/#/trials/{trial['id']}")
    plot = page.get_by_test_id("review-plot-torque")
    expect(page.get_by_test_id("review-stride-count")).to_contain_text("strides", timeout=30_000)  # the trial loaded
    wait_responsive(page)  # the review page's first drawing done
    plot.scroll_into_view_if_needed()
    box = plot.locator(".u-over").bounding_box()
    assert box is not None
    rows = _hover_rows(page, plot, "review-plot-", "torque")
    assert rows[1][2] == '" N·m"', rows
    float(rows[1][1])
    _drag(page, _at(box, 0.2), _at(box, 0.5))
    expect(plot.get_by_test_id("plot-state")).to_contain_text("zoomed")
    for width, height in VIEWPORTS:
        page.set_viewport_size({"width": width, "height": height})
        page.wait_for_timeout(400)
        plot.scroll_into_view_if_needed()
        page.screenshot(path=str(ARTIFACTS / f"plots-review-{width}.png"))
    plot.get_by_test_id("plot-reset").click()
    expect(plot.get_by_test_id("plot-state")).not_to_contain_text("zoomed")
    assert device.error is None, device.error
    watched.check_clean()
