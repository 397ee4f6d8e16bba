"""The IMU calibration card in a real browser against the real server: a device sending raw IMU signals
only (foot and shank) streams over the real websocket while the clinician asks for a standing calibration
from the live view. Standing still: the progress bar runs and each sensor's offset is shown as applied;
then the device walks and a second calibration is refused with each sensor's reason. The fixtures are
``conftest.py``'s (this module gets its own server)."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
from websockets.sync.connection import Connection

from tests.e2e.devices import StreamingDevice, device_session
from tests.e2e.pages import Watched
from tests.waiting import wait_until
from tests.walks import IMU_CHANNELS, IMU_RATE, imu_standing, imu_walking

playwright_api = pytest.importorskip("playwright.sync_api")
expect = playwright_api.expect


class Device(StreamingDevice):
    """Streams frames in real time (100 Hz) to a device session: standing, or walking once asked to."""

    def __init__(self, base: str, session_id: int, token: str):
        super().__init__(base, session_id, token)
        self.walking = threading.Event()
        self.walked = 0  # walking frames sent

    def stream(self, ws: Connection) -> None:
        t, seq = 0.0, 0
        start = time.monotonic()
        while not self.stop.is_set():
            walking = self.walking.is_set()
            frames: list[dict[str, Any]] = imu_walking(t) if walking else imu_standing(t, 1.0, seq)
            for frame in frames:
                if self.stop.is_set():
                    break
                ws.send(json.dumps({**frame, "seq": seq}))
                ws.recv(timeout=5)
                seq += 1
                self.walked += walking
                t = frame["t"] + 1.0 / IMU_RATE
                self.pace(start, seq, IMU_RATE)


@pytest.fixture
def imu_device(server: str) -> Iterator[tuple[int, Device]]:
    with device_session(server, "IMU1", IMU_RATE, IMU_CHANNELS, Device) as opened:
        yield opened


def test_calibrate_from_the_live_view_then_refused_while_walking(
    server: str, watched: Watched, imu_device: tuple[int, Device]
) -> None:
    sid, device = imu_device
    page = watched.page
    page.goto(f"{server}/#/sessions/{sid}")
    card = page.get_by_test_id("imu-card")
    expect(card).to_be_visible(timeout=20_000)  # the stack has IMU front ends: the card shows
    page.get_by_test_id("imu-duration").select_option("2")
    page.get_by_test_id("imu-calibrate").click()
    expect(page.get_by_test_id("imu-bar")).to_be_visible()  # collecting: the progress bar runs
    expect(page.get_by_test_id("imu-applied")).to_be_visible(timeout=20_000)
    for seg in ("foot", "shank"):
        expect(page.get_by_test_id(f"imu-sensor-{seg}")).to_contain_text("pitch offset")
    device.walking.set()
    wait_until(lambda: device.walked >= IMU_RATE or not device.is_alive(), 30.0, "a second of walking")
    assert device.error is None, device.error
    page.get_by_test_id("imu-calibrate").click()
    expect(page.get_by_test_id("imu-refused")).to_be_visible(timeout=20_000)
    expect(page.get_by_test_id("imu-sensor-shank")).to_contain_text("stand still")
    assert device.error is None, device.error
    watched.check_clean()
