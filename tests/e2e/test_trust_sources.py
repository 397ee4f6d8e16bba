"""No invented values on the live screen (issue #23, point 1), in Debian chromium against the real server.

On a +10 deg slope the clinician switches the torque to the timing-based estimate. With the phase EKF in the
stack the incline and stride length shown are the phase EKF's, named as such, and the page says what the torque
assumes in their place; with the timing-based estimate alone they read "not estimated", never 0 deg or the
nominal stride. The recording says the same: null where nothing estimated, never the nominal values.
"""

from __future__ import annotations

import re
from pathlib import Path

from playwright import sync_api as playwright_api

from gaitscope.sessions.formats.mcap_io import read_messages
from gaitscope.sessions.schema import GaitState
from tests.e2e.accounts import call, client, session_time, simulated_session
from tests.e2e.pages import ARTIFACTS, Watched

expect = playwright_api.expect


def _session(server: str, code: str, estimators: list[str] | None) -> int:
    """A running simulated session on a +10 deg slope whose torque follows the timing-based estimate."""
    _, session = simulated_session(server, code, 1.2, 10.0, 400, primary="tbe", estimators=estimators)
    return int(session["id"])


def _tile(page: playwright_api.Page, key: str) -> str:
    return page.get_by_test_id(f"summary-{key}").inner_text().strip()


def test_a_timing_based_primary_on_a_slope_shows_the_phase_ekf_incline_named_as_its(
    server: str, watched: Watched
) -> None:
    _, session = simulated_session(server, "SRC1", 1.2, 10.0, 400)  # the phase EKF drives the torque
    sid = int(session["id"])
    try:
        session_time(server, sid, at_least=12.0)  # the phase EKF has converged on the slope
        page = watched.page
        page.goto(f"{server}/#/sessions/{sid}")
        sources = page.get_by_test_id("summary-sources")
        expect(sources).to_be_hidden()  # every figure is the primary's own
        # "Torque follows": the timing-based estimate, confirmed as every switch is
        page.get_by_test_id("primary-select").select_option("tbe")
        page.get_by_test_id("primary-apply").click()
        page.get_by_test_id("confirm-primary").click()
        expect(sources).to_contain_text("Stride length and incline from Phase EKF (seed 000)")
        expect(sources).to_contain_text("The torque assumes a 1.17 m stride and level ground (Timing-based estimate")
        expect(page.get_by_test_id("summary-incline")).not_to_have_text("–", timeout=15_000)
        for _ in range(5):  # the figure follows the slope, never a level 0.0
            incline = _tile(page, "incline")
            assert re.fullmatch(r"-?\d+\.\d", incline), incline
            assert float(incline) > 4.0, f"incline shown {incline} deg on a +10 deg slope"
            page.wait_for_timeout(300)
        stride = float(_tile(page, "stride-length"))
        assert stride != 1.17 and 0.8 < stride < 2.0
        assert "Phase EKF" in (page.get_by_test_id("summary-incline").locator("..").get_attribute("title") or "")
        page.screenshot(path=str(ARTIFACTS / "trust-sources-tbe-with-ekf.png"))
        assert watched.console_errors == []
    finally:
        call(server, "POST", f"/api/sessions/{sid}/stop")


def test_a_timing_based_estimate_alone_shows_not_estimated_and_records_null(
    server: str, watched: Watched, tmp_path: Path
) -> None:
    sid = _session(server, "SRC2", ["hs_detector", "tbe"])
    try:
        page = watched.page
        page.goto(f"{server}/#/sessions/{sid}")
        trial = call(server, "POST", f"/api/sessions/{sid}/recording", {"action": "start", "name": "slope"})
        for key in ("incline", "stride-length", "speed"):
            expect(page.get_by_test_id(f"summary-{key}")).to_have_text("not estimated", timeout=20_000)
        expect(page.get_by_test_id("summary-cadence")).to_have_text(re.compile(r"^\d+\.\d$"))
        expect(page.get_by_test_id("summary-sources")).to_contain_text(
            "Stride length and incline: not estimated by any estimator of this session."
        )
        expect(page.get_by_test_id("summary-sources")).to_contain_text("The torque assumes a 1.17 m stride")
        page.screenshot(path=str(ARTIFACTS / "trust-sources-tbe-alone.png"))
        session_time(server, sid, at_least=4.0)
        call(server, "POST", f"/api/sessions/{sid}/recording", {"action": "stop"})
        assert watched.console_errors == []
    finally:
        call(server, "POST", f"/api/sessions/{sid}/stop")
    path = tmp_path / "slope.mcap"
    path.write_bytes(client(server, "clinician").raw("GET", f"/api/trials/{trial['id']}/download"))
    states = [GaitState.model_validate(m) for _, _, m in read_messages(path, ["/gait_state"])]
    assert len(states) > 100
    assert all(s.incline_deg is None and s.stride_length_m is None for s in states)
    assert all(s.phase is not None and s.torque_Nm >= 0.0 for s in states)
    assert states[0].sources == {"phase": "tbe", "phase_rate": "tbe"}
    assert states[0].torque_assumes is not None and states[0].torque_assumes["incline_deg"] == 0.0
