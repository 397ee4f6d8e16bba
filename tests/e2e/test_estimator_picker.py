"""The new-session form's estimator picker (issue #26, "selectable") in a real browser against the real server.

From the sessions page a clinician reads each registered estimator (its name on screen, the channels it needs, what
it is for, its cost per sample on this server as the start-up warm-up timed it; the opt-in ones marked, the SDRE
knee's note that it is meant for seated FES-driven legs), chooses the phase EKF, the SDRE knee and the GP-EKF with
the torque following the phase EKF, and starts a simulated session: the live view opens on a session that runs
those three (its settings, the primary's switch, the GP-EKF's learning card, the SDRE knee on the joints plot) with
samples arriving. A choice the browser can tell cannot drive the torque is refused before sending; one the server
refuses (the personalized thigh model for a subject without a calibrated fingerprint: the simulated walker sends
every channel, so no choice lacks one) shows the server's reason in the form. Screenshot:
``tests/e2e/artifacts/estimator-picker.png``.
"""

from __future__ import annotations

import re

import pytest

from tests.e2e.accounts import call
from tests.e2e.pages import ARTIFACTS, Watched

playwright_api = pytest.importorskip("playwright.sync_api")
expect = playwright_api.expect

CHOSEN = ["phase_ekf", "sdre_knee", "gp_ekf"]


def test_choose_estimators_for_a_simulated_session(server: str, watched: Watched) -> None:
    page = watched.page
    watched.allow_refusal(409, r"/api/sessions$")  # the refused choice, on purpose
    subject = call(server, "POST", "/api/subjects", {"code": "PICK1", "leg_length_m": 0.9, "mass_kg": 70.0})
    page.goto(f"{server}/#/")
    page.get_by_test_id("session-subject").select_option(str(subject["id"]))
    page.get_by_test_id("source-simulated").check()

    # --- the default stack until a clinician chooses; then one checkbox per registered estimator -------------------
    picker = page.get_by_test_id("session-estimators")
    expect(picker.locator("legend")).to_have_text("Estimators")
    expect(page.get_by_test_id("estimators-default")).to_be_checked()
    expect(page.get_by_test_id("session-estimator-list")).to_be_hidden()
    expect(page.get_by_test_id("session-estimators-hint")).to_contain_text("except the opt-in ones")
    page.get_by_test_id("estimators-custom").check()
    expect(page.get_by_test_id("session-estimator-list")).to_be_visible()
    registered = call(server, "GET", "/api/estimators")
    rows = page.locator("[data-testid^=session-estimator-row-]")
    expect(rows).to_have_count(len(registered))
    for e in registered:
        row = page.get_by_test_id(f"session-estimator-row-{e['name']}")
        expect(row).to_contain_text(e["label"])
        expect(row).to_have_attribute("data-opt-in", "true" if e["opt_in"] else "false")
        expect(page.get_by_test_id(f"session-estimator-purpose-{e['name']}")).to_have_text(e["purpose"])
        assert e["cost_us"] is not None or e["name"] == "fp_ls", e  # the warm-up timed every one it could build
        if e["cost_us"] is not None:
            expect(page.get_by_test_id(f"session-estimator-needs-{e['name']}")).to_contain_text(
                re.compile(r"about [\d.]+ µs per sample on this server")
            )
    fronts = [e["name"] for e in registered if e["derives"]]  # the IMU front ends and com_kin: folded
    expect(page.get_by_test_id("session-estimator-front-ends").locator("summary")).to_contain_text(
        f"Front ends deriving channels ({len(fronts)})"
    )
    expect(page.get_by_test_id(f"session-estimator-row-{fronts[0]}")).to_be_hidden()
    expect(page.get_by_test_id("session-estimator-row-phase_ekf")).to_be_visible()
    sdre = page.get_by_test_id("session-estimator-row-sdre_knee")
    expect(sdre).to_contain_text("SDRE knee angle from IMUs (seed 002)")
    expect(sdre).to_contain_text("(opt-in)")
    expect(sdre).to_contain_text("Meant for seated, FES-driven legs")
    expect(sdre).to_contain_text("needs imu_thigh_gyro_z_dps, imu_thigh_accel_x_m_s2")
    expect(page.get_by_test_id("session-estimator-row-gp_ekf")).to_contain_text("(opt-in)")
    expect(page.get_by_test_id("session-estimator-phase_ekf")).to_be_checked()  # what the torque follows by default
    expect(page.get_by_test_id("session-estimator-needs-phase_ekf")).to_contain_text(
        "needs foot_angle_deg or shank_angle_deg"
    )

    # --- a choice without a phase cannot drive the torque: refused before sending -----------------------------
    page.get_by_test_id("session-estimator-phase_ekf").uncheck()
    page.get_by_test_id("session-estimator-sdre_knee").check()
    expect(page.get_by_test_id("session-primary")).to_be_disabled()
    page.get_by_test_id("session-submit").click()
    expect(page.get_by_test_id("session-error")).to_contain_text("Choose at least one estimator with a phase")
    assert page.url.endswith("#/")

    # --- one the server refuses: its reason in the form -----------------------------------------------------------
    page.get_by_test_id("session-estimator-fp_ls").check()
    page.get_by_test_id("session-primary").select_option("fp_ls")
    page.get_by_test_id("session-submit").click()
    expect(page.get_by_test_id("session-error")).to_contain_text("cannot start")
    expect(page.get_by_test_id("session-error")).to_contain_text("fp_ls")
    assert page.url.endswith("#/")

    # --- phase EKF, SDRE knee and GP-EKF, the torque following the phase EKF --------------------------------------
    page.get_by_test_id("session-estimator-fp_ls").uncheck()
    page.get_by_test_id("session-estimator-phase_ekf").check()
    page.get_by_test_id("session-estimator-gp_ekf").check()
    primary = page.get_by_test_id("session-primary")
    expect(primary.locator("option")).to_have_text(["Phase EKF (seed 000)", "GP-EKF (seed 003) (stance phase)"])
    expect(primary).to_have_value("phase_ekf")
    expect(page.get_by_test_id("session-estimators-hint")).to_contain_text(
        re.compile(r"3 chosen, together about [\d.]+ µs per sample on this server")
    )
    ARTIFACTS.mkdir(exist_ok=True)
    picker.screenshot(path=str(ARTIFACTS / "estimator-picker.png"))
    page.get_by_test_id("session-submit").click()
    page.wait_for_url(re.compile(r"#/sessions/\d+$"), timeout=30_000)
    sid = int(page.url.rsplit("/", 1)[1])
    try:
        session = call(server, "GET", f"/api/sessions/{sid}")
        assert session["state"] == "running"
        assert session["settings"]["estimators"] == CHOSEN and session["settings"]["primary"] == "phase_ekf"
        assert session["source"]["kind"] == "simulated"

        # --- the live view runs them, and samples arrive ----------------------------------------------------------
        expect(page.get_by_test_id("live-indicator")).to_have_text("LIVE", timeout=30_000)
        expect(page.get_by_test_id("health-primary")).to_have_text("Phase EKF (seed 000)", timeout=10_000)
        expect(page.get_by_test_id("primary-select").locator("option")).to_have_text(
            ["Phase EKF (seed 000)", "GP-EKF (seed 003)"], timeout=10_000
        )  # the stack's estimators with a phase, nothing the picker left out
        expect(page.get_by_test_id("gp-card")).to_be_visible(timeout=20_000)  # the GP-EKF runs: its learning card
        expect(page.get_by_test_id("plot-joints").locator(".u-legend")).to_contain_text("knee, SDRE from IMUs")
        phase_legend = page.get_by_test_id("plot-phase").locator(".u-legend")
        expect(phase_legend).to_contain_text("Phase EKF (seed 000)")
        expect(phase_legend).not_to_contain_text("Timing-based estimate")  # not chosen, not run
        first = page.get_by_test_id("summary-phase").text_content()
        page.wait_for_timeout(1000)
        assert page.get_by_test_id("summary-phase").text_content() != first  # the phase moves: samples arrive
        expect(page.get_by_test_id("health-failed-estimators")).to_have_text("none")
    finally:
        call(server, "POST", f"/api/sessions/{sid}/stop")
    watched.check_clean()
