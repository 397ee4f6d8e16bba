"""Re-runs that reproduce (issue #23, 2), in a real browser against the real server: a live simulated session
records a first trial with a primary switch and a gain change in it, has another switch and gain change between
the trials, and records a second trial with a third switch and gain change; the review of the second trial,
re-run "as recorded", shows a largest torque difference from the recording of 0 N·m, from its first sample.
The fixtures are ``conftest.py``'s (this module gets its own server).
"""

from __future__ import annotations

import time
from typing import Any

import pytest

from gaitscope.sessions import schema
from tests.e2e.accounts import Refused, call, session_time, simulated_session
from tests.e2e.pages import ARTIFACTS, Watched

playwright_api = pytest.importorskip("playwright.sync_api")
expect = playwright_api.expect

#: Session seconds between two changes that can raise the torque: past the server's rate limits.
SPACING_S = 3.5


def _change(server: str, sid: int, **fields: Any) -> None:
    """A settings change by another clinician, made once the server's rate limit (its wall clock) lets it."""
    if "confirm" in schema.SettingsChange.model_fields:  # the torque rule: the user agreed to the peaks shown
        fields["confirm"] = True
    for _ in range(3):
        try:
            call(server, "PATCH", f"/api/sessions/{sid}/settings", fields, user="admin")
            return
        except Refused as e:
            if not (isinstance(e.detail, dict) and e.detail.get("reason") == "too_soon"):
                raise
            time.sleep(float(e.detail["retry_after_s"]) + 0.1)  # the server's clock: what the limit says to wait
    raise AssertionError(f"the change {fields} was refused as too soon three times")


def _recording(server: str, sid: int, action: str, name: str = "") -> dict[str, Any]:
    body = {"action": action, **({"name": name} if name else {})}
    trial: dict[str, Any] = call(server, "POST", f"/api/sessions/{sid}/recording", body)
    return trial


def test_a_mid_session_trial_reruns_as_recorded_with_no_torque_difference(server: str, watched: Watched) -> None:
    _, session = simulated_session(server, "TR01", 1.2, 4.0, 400)
    sid = session["id"]
    try:
        # the first trial (recording since the start): a primary switch, then a gain change
        t = session_time(server, sid, 2.0)
        _change(server, sid, primary="tbe")
        t = session_time(server, sid, t + SPACING_S)
        _change(server, sid, torque_gain=1.2)
        t = session_time(server, sid, t + 2.0)
        first = _recording(server, sid, "stop")
        assert first["status"] == "finished"
        # between the trials: switch back, another gain
        t = session_time(server, sid, t + SPACING_S)
        _change(server, sid, primary="phase_ekf")
        t = session_time(server, sid, t + SPACING_S)
        _change(server, sid, torque_gain=1.4)
        t = session_time(server, sid, t + 0.5)  # the switch's blend still running when the second trial starts
        second = _recording(server, sid, "start", "second")
        # the second trial: another switch and gain change
        t = session_time(server, sid, t + SPACING_S)
        _change(server, sid, primary="tbe")
        t = session_time(server, sid, t + SPACING_S)
        _change(server, sid, torque_gain=0.9)
        session_time(server, sid, t + 2.0)
        stopped = _recording(server, sid, "stop")
        assert stopped["id"] == second["id"] != first["id"] and stopped["status"] == "finished"
    finally:
        call(server, "POST", f"/api/sessions/{sid}/stop")

    page = watched.page
    page.goto(f"{server}/#/trials/{second['id']}")
    expect(page.get_by_test_id("rerun-change")).to_have_count(2)  # the two changes inside the second trial
    submit = page.get_by_test_id("rerun-submit")
    expect(submit).to_be_enabled()
    expect(page.get_by_test_id("rerun-mode-recorded")).to_be_checked()
    submit.click()
    expect(page.get_by_test_id("rerun-ok")).to_contain_text("the recorded settings", timeout=60_000)
    diff = page.get_by_test_id("rerun-torque-diff")
    expect(diff).to_have_attribute("data-value", "0")
    expect(diff).to_have_text("0 N·m (identical to what ran)")
    expect(page.get_by_test_id("rerun-fidelity")).to_contain_text("Resumed from the estimation state recorded")
    page.get_by_test_id("rerun-card").screenshot(path=str(ARTIFACTS / "trust-rerun.png"))
    # the recorded torque was not flat: the figure compares something
    series = call(server, "GET", f"/api/trials/{second['id']}/series?max_points=2000")
    assert max(series["torque_Nm"]) > 5.0
