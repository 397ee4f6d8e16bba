"""The GP-EKF's learning card (seed 003, issue #11) in a real browser against the real server: a device whose
session's stack runs ``gp_ekf`` streams seed 003's sinusoidal-speed walk (joint encoders and heel strikes,
200 Hz) over the real websocket, a little faster than real time (the server admits 1.25 x the declared rate).

The card appears; its stance-phase plot follows the walk's true stance phase and the gait-phase plot leaves
the GP-EKF out; the learned hip, knee and ankle bands are drawn (mean inside its +-2 SD band, the previous
version faintly) and redrawn as retraining installs new versions; each retraining is an event with its
training window and held-out RMSE, readable in the event list; Freeze is logged with the acting user and
shown, a rollback to the population model waits for the next heel strike and is then installed; a refused
rollback (422) and the session's stop (409) are shown in plain words. Values are read from the plots'
legends under the mouse, as a clinician reads them. The fixtures are ``conftest.py``'s (this module gets
its own server); screenshots of the card and the live view go to ``tests/e2e/artifacts/`` (``gp-*.png``).
"""

from __future__ import annotations

import functools
import json
import re
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import numpy as np
import pytest
from websockets.sync.connection import Connection

from tests.e2e.accounts import call, log_in
from tests.e2e.devices import StreamingDevice, device_session
from tests.e2e.pages import ARTIFACTS, Watched, sweep

if TYPE_CHECKING:
    from playwright.sync_api import Page

playwright_api = pytest.importorskip("playwright.sync_api")
expect = playwright_api.expect


RATE = 200.0  # Hz, declared and in the frames' times
SEND_HZ = 240.0  # frames per second sent: under the 1.25 x RATE the server admits (LiveDevice's headroom)
CHANNELS = ["foot_angle_deg", "foot_vel_dps", "shank_angle_deg", "shank_vel_dps", "thigh_angle_deg", "thigh_vel_dps",
            "hip_angle_deg", "knee_angle_deg", "ankle_angle_deg", "heel_strike"]  # fmt: skip
STACK = ["phase_ekf", "tbe", "gp_ekf"]
GP_URL = r"/api/sessions/\d+/gp-learning"


@functools.cache
def _walk() -> tuple[list[dict[str, Any]], np.ndarray]:
    """Seed 003's walk of the cohort's first subject (90 s at 0.4-1.2 m/s), as device frames, and its true
    stance phase sample by sample (0..1, NaN in swing)."""
    from gaitscope.sessions.live.sources import frames_from_table
    from gaitscope.sessions.synth.cohort import CohortSpec, make_subjects
    from gaitscope.sessions.synth.speed_walks import SpeedProtocol, speed_walk

    walk = speed_walk(make_subjects(CohortSpec())[0], SpeedProtocol(walk_s=90.0, standing_s=1.0, rate_hz=RATE))
    frames = [{"type": "frame", "t": f.t, **f.model_dump(include=set(CHANNELS))} for f in frames_from_table(walk)]
    return frames, walk["gt_stance_phase"].to_numpy(np.float64)


class Device(StreamingDevice):
    """Sends the walk once at ``SEND_HZ``, each frame answered by a torque; session time is the frames' time."""

    def stream(self, ws: Connection) -> None:
        frames, _ = _walk()
        start = time.monotonic()
        for k, frame in enumerate(frames):
            if self.stop.is_set():
                break
            ws.send(json.dumps({**frame, "seq": k}))
            ws.recv(timeout=5)
            self.pace(start, k + 1, SEND_HZ)

    @staticmethod
    def stance(t: float) -> float:
        """The true stance phase (0..1; NaN in swing) at session time ``t`` (the walk's time)."""
        truth = _walk()[1]
        return float(truth[min(round(t * RATE), len(truth) - 1)])


@pytest.fixture
def gp_session(server: str) -> Iterator[tuple[int, Device]]:
    _walk()  # made before the session starts, so that the device streams at once
    with device_session(server, "GPE1", RATE, CHANNELS, Device, STACK) as opened:
        yield opened


def _version(page: Page) -> int:
    return int(page.get_by_test_id("gp-version").get_attribute("data-version") or "-1")


def test_learning_card_bands_versions_freeze_and_rollback(
    server: str, watched: Watched, gp_session: tuple[int, Device]
) -> None:
    sid, device = gp_session
    page = watched.page
    watched.allow_refusal(422, GP_URL)  # a rollback to a version that is not kept, on purpose
    watched.allow_refusal(409, GP_URL)  # the session stopped at the end, on purpose
    page.goto(f"{server}/#/sessions/{sid}")
    card = page.get_by_test_id("gp-card")
    expect(card).to_be_visible(timeout=20_000)  # the stack runs gp_ekf: the card shows
    expect(card.locator("h2")).to_have_text("Learning gait model (GP-EKF, seed 003)")
    log_in(page.context, server, "experimenter")  # the experimenter runs the learning (a Runner's controls)
    page.reload()
    expect(card).to_be_visible(timeout=20_000)

    # --- the stance phase: in the card, following the walk; not on the gait-phase plot --------------------
    phase_legend = page.get_by_test_id("plot-phase").locator(".u-legend")
    expect(phase_legend).to_contain_text("Timing-based estimate")  # by their labels (issue #23)
    expect(phase_legend).to_contain_text("Phase EKF (seed 000)")
    expect(phase_legend).not_to_contain_text("GP-EKF")
    in_stance: list[tuple[float, float]] = []
    for _ in range(6):  # a few stances in the 10 s window (the device streams slower on a loaded machine)
        page.wait_for_timeout(3000)
        readings = sweep(page, page.get_by_test_id("gp-stance-plot"), np.linspace(0.3, 0.98, 60))
        pairs = [(r["t (s)"], r["stance phase"]) for r in readings]
        assert all(t is not None and v is not None and 0.0 <= v <= 100.0 for t, v in pairs), pairs
        stance = [(v, 100 * Device.stance(t)) for t, v in pairs if t is not None and v is not None]
        in_stance = [(v, true) for v, true in stance if np.isfinite(true)]
        if len(in_stance) >= 10:
            break
    assert len(in_stance) >= 10, stance
    err = np.abs(np.subtract(*zip(*in_stance, strict=True)))
    assert float(np.median(err)) < 12.0, in_stance  # within a tenth of the stance, the population model's

    # --- retraining: a new version installed, its bands drawn, an event with its window and fit ----------
    # the first fit waits for the worker process to start and import GPy; a window the held-back check refuses
    # is retried 5 steps later. Under a loaded 2-core machine the device streams late, the worker is slow to start
    # and fits at most its duty share (seen: no model within 70 s at load 8; the whole test took 90 s at load 5)
    version = page.get_by_test_id("gp-version")
    try:
        expect(version).to_have_text(re.compile(r"^v[1-9]\d*$"), timeout=150_000)
    except AssertionError:
        learning = call(server, "GET", f"/api/sessions/{sid}/gp-learning")
        raise AssertionError(f"no model installed; device {device.error!r}; the learning: {learning!r:.600}") from None
    first = _version(page)
    for joint in ("hip", "knee", "ankle"):
        plot = page.get_by_test_id(f"gp-band-{joint}")
        for attempt in range(3):  # learning goes on: a newer version may install (and redraw) mid-check
            now = _version(page)
            try:
                assert now >= first, (now, first)
                expect(plot).to_have_attribute("data-version", str(now), timeout=5000)
                legend = plot.locator(".u-legend")
                expect(legend).to_contain_text(f"v{now} mean", timeout=5000)
                expect(legend).to_contain_text("(previous)", timeout=5000)  # the version before it, faintly
                for r in sweep(page, plot, np.linspace(0.1, 0.9, 5)):
                    prev = r[next(k for k in r if "previous" in k)]
                    mean, lo, hi = r[f"v{now} mean"], r["−2 SD"], r["+2 SD"]
                    assert mean is not None and lo is not None and hi is not None and prev is not None, r
                    assert lo < mean < hi and hi - lo < 40.0, r  # a band of a few degrees about the mean
                break
            except (AssertionError, StopIteration, KeyError):
                if attempt == 2 or _version(page) == now:
                    raise  # not a version change: a real failure
    rows = page.get_by_test_id("event-row").filter(has_text="GP model v1 trained on steps 1-5")
    expect(rows).to_have_count(1)
    expect(rows.get_by_test_id("event-text")).to_have_text(
        re.compile(r"GP model v1 trained on steps 1-5 \(\d+\.\d-\d+\.\d s\), held-out RMSE hip \d+\.\d, knee \d+\.\d, "
                   r"ankle \d+\.\d deg: installed at \d+\.\d\d s"))  # fmt: skip
    expect(rows.get_by_test_id("event-change")).to_have_text("GP-EKF model: v0 → v1")
    row = page.get_by_test_id("gp-version-row").and_(page.locator('[data-version="1"]'))
    expect(row).to_contain_text("1–5")
    expect(row.locator("td")).to_have_text([re.compile(r"1–5"), re.compile(r"^\d+\.\d–\d+\.\d$"),
        *[re.compile(r"^\d+\.\d$")] * 3, re.compile(r"^\d+\.\d")])  # fmt: skip
    # as learning goes on the bands are redrawn for each new version
    try:
        expect(page.get_by_test_id("gp-version")).not_to_have_text(f"v{first}", timeout=150_000)  # as the first
    except AssertionError:
        learning = call(server, "GET", f"/api/sessions/{sid}/gp-learning")
        why = f"device {device.error!r}; the learning: {learning!r:.600}"
        raise AssertionError(f"no model after v{first}; {why}") from None
    second = _version(page)
    assert second > first
    expect(page.get_by_test_id("gp-band-knee")).to_have_attribute("data-version", str(second))
    expect(page.get_by_test_id("gp-band-knee").locator(".u-legend")).to_contain_text(f"v{second} mean")

    # --- freeze: logged with the acting user, shown ---------------------------------------------------------
    page.get_by_test_id("gp-reason").fill("e2e: hold the model")
    page.get_by_test_id("gp-freeze").click()
    expect(page.get_by_test_id("gp-frozen")).to_be_visible()
    expect(page.get_by_test_id("gp-freeze")).to_have_text("Unfreeze learning")
    expect(page.get_by_test_id("gp-ok")).to_contain_text("Learning frozen")
    frozen = page.get_by_test_id("event-row").filter(has_text="GP learning frozen by experimenter")
    expect(frozen.get_by_test_id("event-text")).to_contain_text("(e2e: hold the model)")
    expect(frozen.get_by_test_id("event-actor")).to_have_text("by experimenter")
    expect(frozen.get_by_test_id("event-change")).to_have_text("GP-EKF model: learning → frozen")

    # --- roll back to the population model: waiting for a heel strike, then installed ---------------------
    page.get_by_test_id("gp-rollback-version").select_option("0")
    expect(page.get_by_test_id("gp-band-hip")).to_have_attribute("data-compare", "0")  # drawn faintly to compare
    expect(page.get_by_test_id("gp-rollback")).to_have_text("Roll back to v0")
    page.get_by_test_id("gp-rollback").click()
    expect(page.get_by_test_id("gp-ok")).to_contain_text("Rollback to v0 asked")
    expect(page.get_by_test_id("gp-version")).to_have_text("v0", timeout=10_000)
    expect(page.get_by_test_id("gp-status")).to_contain_text("(population model)")
    expect(page.get_by_test_id("gp-frozen")).to_be_visible()  # still frozen: v0 stays
    expect(page.get_by_test_id("event-row").filter(has_text="GP model rollback to v0 by experimenter")).to_have_count(1)
    expect(page.get_by_test_id("event-row").filter(has_text="GP model v0 reinstalled")).to_have_count(1)
    expect(page.get_by_test_id("gp-band-ankle")).to_have_attribute("data-version", "0")
    assert device.error is None, device.error
    ARTIFACTS.mkdir(exist_ok=True)
    card.screenshot(path=str(ARTIFACTS / "gp-learning.png"))
    page.screenshot(path=str(ARTIFACTS / "gp-live.png"), full_page=True)

    # --- refusals in plain words: a version no longer kept (a list drawn before it went), the session stopped
    page.evaluate(
        """() => {
        const sel = document.querySelector('[data-testid="gp-rollback-version"]');
        sel.add(new Option("v99", "99"));
        sel.value = "99";
        document.querySelector('[data-testid="gp-rollback"]').click();
    }"""
    )
    expect(page.get_by_test_id("gp-error")).to_have_text(
        re.compile(r"^Not accepted: GP model v99 is not kept; a rollback can reinstall v0, v1, .*")
    )
    assert _version(page) == 0
    device.stop.set()
    device.join(timeout=10)
    call(server, "POST", f"/api/sessions/{sid}/stop")
    expect(page.get_by_test_id("gp-note")).to_contain_text("not running")
    expect(page.get_by_test_id("gp-freeze")).to_be_disabled()
    expect(page.get_by_test_id("gp-rollback")).to_be_disabled()
    assert device.error is None, device.error
    watched.check_clean()
