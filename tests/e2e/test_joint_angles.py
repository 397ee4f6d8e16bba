"""The hip and knee flexion plot in a real browser against the real server, from IMUs alone: a device sending
raw gyro and accelerometer channels only (foot, shank and thigh IMUs, no angle) walks over the real websocket,
its stack running the IMU front ends and the SDRE knee estimator (``sdre_knee``). The live view's hip and knee
plot draws finite angles that follow the walk (each correlated with the simulated thigh's or knee's angle, so
a missing, empty, swapped or sign-flipped series fails), the SDRE's knee dashed beside them; a recording of the
walk reviewed shows them too, and a re-run of its stack overlays the SDRE knee. The front ends' accuracy is
``tests/estimators``' to check, not this test's. Values are read from the plots' legends under the mouse, as a
clinician reads them. The fixtures are ``conftest.py``'s (this module gets its own server)."""

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

from gaitscope.estimators.imu_frontend import imu_inputs
from tests.e2e.accounts import call, record
from tests.e2e.devices import StreamingDevice, device_session
from tests.e2e.pages import Watched, sweep

if TYPE_CHECKING:
    pass

playwright_api = pytest.importorskip("playwright.sync_api")
expect = playwright_api.expect


RATE = 100.0
CHANNELS = [c for seg in ("foot", "shank", "thigh") for c in imu_inputs(seg)]
STACK = ["imu_foot", "imu_shank", "imu_thigh", "hs_detector", "phase_ekf", "tbe", "sdre_knee"]
SAMPLES = 24  # mouse positions a plot is read at
#: the hip and knee plot's legend labels
HIP, KNEE, SDRE = "hip (thigh from vertical)", "knee (thigh − shank)", "knee, SDRE from IMUs"


@functools.cache
def _walk() -> tuple[list[dict[str, Any]], dict[str, np.ndarray]]:
    """A simulated walk's frames, raw IMU channels only, and its true ``thigh`` angle and ``knee`` flexion
    (deg) sample by sample."""
    from gaitscope.sessions.live.sources import frames_from_table
    from gaitscope.sessions.synth.trials import sensor_trial

    sensors, _, _ = sensor_trial([(1.0, 0.0, 12)], rate_hz=RATE)
    frames = [{"type": "frame", "t": f.t, **f.model_dump(include=set(CHANNELS))} for f in frames_from_table(sensors)]
    truth = {"thigh": sensors["thigh_angle_deg"], "knee": sensors["knee_angle_deg"]}
    return frames, {k: v.to_numpy(np.float64) for k, v in truth.items()}


class Device(StreamingDevice):
    """Sends the walk in real time, over and over (session time running on), each frame answered by a torque."""

    def __init__(self, base: str, session_id: int, token: str):
        super().__init__(base, session_id, token)
        self.period = len(_walk()[0]) / RATE  # s: the walk's length; the n-th pass starts at n periods

    def stream(self, ws: Connection) -> None:
        frames, _ = _walk()
        seq = 0
        start = time.monotonic()
        while not self.stop.is_set():
            for k, frame in enumerate(frames):
                if self.stop.is_set():
                    break
                lap = seq // len(frames)
                ws.send(json.dumps({**frame, "t": lap * self.period + k / RATE, "seq": seq}))
                ws.recv(timeout=5)
                seq += 1
                self.pace(start, seq, RATE)

    def truth(self, angle: str, t: float) -> float:
        """The simulated ``thigh`` or ``knee`` angle (deg) at session time ``t``."""
        x = _walk()[1][angle]
        return float(x[round((t % self.period) * RATE) % len(x)])


@pytest.fixture
def imu_session(server: str) -> Iterator[tuple[int, Device]]:
    with device_session(server, "JNT1", RATE, CHANNELS, Device, STACK) as opened:
        yield opened


def _follows(device: Device, readings: list[dict[str, float | None]], label: str, angle: str, min_r: float) -> None:
    """Every reading of the series ``label`` is a number, correlated with the simulated ``angle`` by more
    than ``min_r``."""
    pairs = [(r["t (s)"], r[label]) for r in readings]
    got = [(t, v) for t, v in pairs if t is not None and v is not None]
    assert len(got) == len(pairs), (label, readings)  # the cursor on the data, and the series drawn there
    r = float(np.corrcoef([v for _, v in got], [device.truth(angle, t) for t, _ in got])[0, 1])
    assert r > min_r, (label, r, got)


def test_hip_and_knee_from_raw_imus_live_and_in_review(
    server: str, watched: Watched, imu_session: tuple[int, Device]
) -> None:
    sid, device = imu_session
    page = watched.page
    page.goto(f"{server}/#/sessions/{sid}")
    expect(page.get_by_test_id("live-indicator")).to_have_text("LIVE", timeout=20_000)
    # data health has an IMU line for a device with IMU front ends: "ok", or the open problem in words
    expect(page.get_by_test_id("health-imu")).to_have_text(re.compile(r"^(ok|.+IMU.+)$"), timeout=10_000)
    plot = page.get_by_test_id("plot-joints")
    expect(plot.locator(".u-title")).to_have_text("Hip and knee flexion (the hip assumes an upright pelvis)")
    expect(plot.locator(".u-legend")).to_contain_text(SDRE)  # the stack runs sdre_knee: its knee joins, dashed
    page.wait_for_timeout(6000)  # a few strides in the 10 s window

    # --- live: under the mouse, across the newest half of the window, each series follows the walk ---------
    readings = sweep(page, plot, np.linspace(0.5, 0.98, SAMPLES))
    _follows(device, readings, HIP, "thigh", 0.8)
    _follows(device, readings, KNEE, "knee", 0.8)
    _follows(device, readings, SDRE, "knee", 0.6)

    # --- review: a recording of the walk; a re-run of its stack overlays the SDRE knee ---------------------
    call(server, "POST", f"/api/sessions/{sid}/recording", {"action": "stop"})  # the session's own "trial 1"
    trial = record(server, sid, 5.0, "walk from IMUs")
    page.goto(f"{server}/#/trials/{trial['id']}")
    review_plot = page.get_by_test_id("review-plot-joints")
    expect(review_plot.locator(".u-title")).to_contain_text("Hip and knee flexion")
    expect(page.get_by_test_id("review-stride-count")).to_contain_text("strides", timeout=30_000)  # the trial loaded
    expect(page.get_by_test_id("review-knee-note")).to_be_hidden()  # 500 samples: every one is shown
    readings = sweep(page, review_plot, np.linspace(0.02, 0.98, SAMPLES))
    _follows(device, readings, HIP, "thigh", 0.8)
    _follows(device, readings, KNEE, "knee", 0.8)
    page.get_by_test_id("rerun-submit").click()
    expect(page.get_by_test_id("rerun-ok")).to_contain_text("Overlaid", timeout=60_000)
    rerun = "SDRE knee angle from IMUs (seed 002), re-run"
    expect(review_plot.locator(".u-legend")).to_contain_text(rerun)
    # the re-run's SDRE starts cold mid-walk (its state at the trial's start is not recorded): past its first
    # 2 s of settling it follows the knee
    _follows(device, sweep(page, review_plot, np.linspace(0.4, 0.98, SAMPLES)), rerun, "knee", 0.6)
    assert device.error is None, device.error
    watched.check_clean()
