"""The dashboard in a real browser against the real server (``gaitscope serve`` as a subprocess).

A clinician's path through it: create a subject and a simulated session, watch the live plots move,
change the torque gain (and see a too-large and a too-soon change refused), annotate, upload a replay
CSV (and see a broken MCAP refused), then review the upload, scrub it, re-run it with other settings and
re-run chosen estimators of its stack, each overlaid and named in the legend.
Screenshots of the live and review views go to ``tests/e2e/artifacts/``. Every test also checks that
the page logged no console error and that no request left 127.0.0.1.

The server runs with accounts on (issue #13), with one user per role (``tests/e2e/accounts.py``); the
``watched`` page is logged in as the clinician, other screens log in as whom they play.
"""

from __future__ import annotations

import re
from pathlib import Path

from playwright import sync_api as playwright_api

from tests.e2e.accounts import client
from tests.e2e.pages import ARTIFACTS, Watched, wait_responsive
from tests.waiting import wait_until


def _patch(base: str, path: str, body: dict[str, object], user: str = "experimenter") -> object:
    """A PATCH from outside the browser: another user's screen."""
    return client(base, user).call("PATCH", path, body)


def _raise_allowed(base: str, session_id: int, change: dict[str, object]) -> None:
    """Wait until the server's torque rule allows the next change that can raise the torque (3 s after the last)."""
    path = f"/api/sessions/{session_id}/settings/check"
    wait_until(lambda: client(base).call("POST", path, change)["retry_after_s"] == 0, 10.0, "the next raise allowed")


def _number(text: str | None) -> float:
    assert text is not None and re.fullmatch(r"-?\d+(\.\d+)?", text.strip()), f"not a number: {text!r}"
    return float(text)


def _replay_csv(path: Path, strides: int = 20) -> Path:
    from gaitscope.sessions.synth.trials import replay_columns, sensor_trial

    sensors, _, _ = sensor_trial(schedule=[(1.2, 0.0, strides)])
    replay_columns(sensors).to_csv(path, index=False)
    return path


def test_no_request_leaves_loopback(server: str, watched: Watched) -> None:
    page = watched.page
    page.goto(f"{server}/")
    playwright_api.expect(page.get_by_test_id("server-status")).to_contain_text("ok")
    page.wait_for_url(re.compile(r"#/sessions/1$"))  # the bare URL opens the running demo session
    page.goto(f"{server}/#/sessions/1")  # the demo session, with the leg view iframe
    playwright_api.expect(page.get_by_test_id("live-indicator")).to_have_text("LIVE", timeout=20_000)
    playwright_api.expect(page.get_by_title("3D leg view")).to_be_visible()
    page.wait_for_timeout(2000)  # let the iframe load its assets
    assert watched.requests > 5
    watched.check_clean()


def test_clinician_flow(server: str, watched: Watched, tmp_path: Path) -> None:
    page = watched.page
    expect = playwright_api.expect
    ARTIFACTS.mkdir(exist_ok=True)

    watched.allow_refusal(409, r"/api/subjects$")  # a duplicate subject code
    watched.allow_refusal(409, r"/api/sessions/\d+/settings$")  # a change too soon after the last
    watched.allow_refusal(422, r"/api/uploads/\w+/finish$")  # a broken MCAP

    # --- a subject: invalid input is refused before sending; a duplicate code by the server (409) ---
    page.goto(f"{server}/#/")
    page.get_by_test_id("subject-code").fill("E2E01")
    page.get_by_test_id("subject-leg").fill("2.0")
    page.get_by_test_id("subject-submit").click()
    expect(page.get_by_test_id("subject-error")).to_have_text("Leg length must be at most 1.3.")
    page.get_by_test_id("subject-leg").fill("0.92")
    page.get_by_test_id("subject-mass").fill("72")
    page.get_by_test_id("subject-submit").click()
    expect(page.get_by_test_id("subject-ok")).to_contain_text("Subject E2E01 created")
    page.get_by_test_id("subject-code").fill("E2E01")
    page.get_by_test_id("subject-submit").click()
    expect(page.get_by_test_id("subject-error")).to_contain_text("Refused: subject code 'E2E01' exists")

    # --- a simulated session; the view follows it -------------------------------------------------
    subject_id = page.get_by_test_id("session-subject").locator("option", has_text="E2E01").get_attribute("value")
    assert subject_id
    page.get_by_test_id("session-subject").select_option(subject_id)
    page.get_by_test_id("source-simulated").check()
    page.get_by_test_id("session-submit").click()
    page.wait_for_url(re.compile(r"#/sessions/\d+$"))
    session_id = int(page.url.rsplit("/", 1)[1])
    assert session_id >= 2  # the demo session is 1

    # --- live data move ---------------------------------------------------------------------------
    expect(page.get_by_test_id("live-indicator")).to_have_text("LIVE", timeout=20_000)
    expect(page.get_by_test_id("live-title")).to_contain_text("E2E01")
    first = _number(page.get_by_test_id("summary-phase").text_content())
    page.wait_for_timeout(1000)
    second = _number(page.get_by_test_id("summary-phase").text_content())
    assert first != second
    assert 0.0 <= second <= 100.0
    expect(page.get_by_test_id("health-rate")).to_contain_text("Hz")
    expect(page.get_by_test_id("health-clients")).not_to_have_text("–")
    expect(page.get_by_test_id("stride-count")).to_contain_text("stride", timeout=20_000)
    assert _number(page.get_by_test_id("summary-cadence").text_content()) > 20  # strides/min while walking
    # the simulated walker sends what seed 001's intent filter reads: its indicator says what the walker does
    expect(page.get_by_test_id("summary-intent")).to_have_text(
        re.compile(r"^(speeding up|steady|slowing down)$"), timeout=20_000
    )
    # ... and its desired vs actual speed are plotted, as the stack has the intent estimator
    intent_plot = page.get_by_test_id("plot-intent-speed")
    expect(intent_plot.locator("canvas")).to_be_visible()
    expect(intent_plot.locator(".u-title")).to_have_text("Speed-change intent: desired vs actual speed")
    expect(intent_plot.locator(".u-legend")).to_contain_text("desired")
    # the simulated device sends segment angles, so its stack runs no IMU front end: nothing to calibrate
    expect(page.get_by_test_id("imu-card")).to_be_hidden()

    # --- the subject's baseline: kept per subject in this browser, survives a reload ---------------------
    expect(page.get_by_test_id("baseline-note")).to_have_text("no baseline")
    page.get_by_test_id("set-baseline").click()
    expect(page.get_by_test_id("baseline-note")).to_contain_text("baseline: ")
    page.reload()
    expect(page.get_by_test_id("baseline-note")).to_contain_text("baseline: ", timeout=15_000)

    # The leg view (viser, WebGL) loads lazily and keeps the renderer busy while it starts; load it
    # first so that the timing of the next steps is the UI's own.
    page.get_by_title("3D leg view").scroll_into_view_if_needed()
    page.frame_locator("iframe[title='3D leg view']").locator("canvas").first.wait_for(state="attached", timeout=30_000)
    wait_responsive(page)

    # --- torque gain 1.0 -> 1.3; a change again too soon (server 409) and too large a step (client) ----
    gain = page.get_by_test_id("setting-torque_gain")
    expect(gain).to_have_value("1")
    gain.fill("1.3")
    page.get_by_test_id("settings-apply").click()
    page.get_by_test_id("confirm-raise").click()  # a raise asks first, with the peak torques (test_trust_confirm)
    expect(page.get_by_test_id("settings-ok")).to_have_text("Applied: Torque gain.")
    gain.fill("1.8")  # a step of 0.5 is allowed, but a raise only 3 s after the last
    page.get_by_test_id("settings-apply").click()
    expect(page.get_by_test_id("settings-error")).to_contain_text("Not yet: a change that can raise the torque")
    gain.fill("2.9")
    page.get_by_test_id("settings-apply").click()
    expect(page.get_by_test_id("settings-error")).to_contain_text("Torque gain may change by at most 0.5 per step")
    page.get_by_test_id("settings-revert").click()
    expect(gain).to_have_value("1.3")
    setting_row = page.get_by_test_id("event-row").and_(page.locator("[data-kind=setting]"))
    expect(setting_row).to_have_count(1)
    expect(setting_row.get_by_test_id("event-text")).to_have_text("Torque gain 1.00 → 1.30, by clinician")

    # --- an experimenter's screen changes the maximum torque (within the subject's limits, which a clinician
    # set): the controls and the events follow ------------------------------------------------------------------
    limits = {"torque_gain": 2.0, "max_torque_Nm": 40.0, "intent_gain_boost": 0.3}
    client(server, "clinician").call("PUT", f"/api/subjects/{subject_id}/assistance-limits", limits)
    _raise_allowed(server, session_id, {"max_torque_Nm": 35.0})
    _patch(server, f"/api/sessions/{session_id}/settings", {"max_torque_Nm": 35.0, "confirm": True})
    expect(page.get_by_test_id("setting-max_torque_Nm")).to_have_value("35")
    expect(page.get_by_test_id("setting-max_torque_Nm-note")).to_have_text("changed elsewhere to 35.0")
    expect(setting_row).to_have_count(2)
    expect(setting_row.first.get_by_test_id("event-text")).to_have_text(
        "Maximum torque 30.0 N·m → 35.0 N·m, by experimenter"
    )

    # --- every estimator's phase overlaid, the primary named; switching it is a logged setting -----------
    expect(page.get_by_test_id("health-primary")).to_have_text("Phase EKF (seed 000)")  # its label (issue #23)
    expect(page.get_by_test_id("health-failed-estimators")).to_have_text("none")
    for label in ("Phase EKF (seed 000) (primary: drives the torque)", "Timing-based estimate"):
        expect(page.get_by_test_id("plot-phase")).to_contain_text(label)
    page.get_by_test_id("primary-select").select_option("tbe")
    _raise_allowed(server, session_id, {"primary": "tbe"})
    page.get_by_test_id("primary-apply").click()
    page.get_by_test_id("confirm-primary").click()  # it changes what drives the torque: it asks first
    expect(page.get_by_test_id("health-primary")).to_have_text("Timing-based estimate", timeout=5_000)
    expect(page.get_by_test_id("plot-phase")).to_contain_text("Timing-based estimate (primary: drives the torque)")
    expect(setting_row).to_have_count(3)
    expect(setting_row.first.get_by_test_id("event-text")).to_have_text(
        re.compile(r"^Torque follows .+ → .+, by clinician$")
    )

    # --- an annotation ---------------------------------------------------------------------------------
    page.get_by_test_id("annotation-add").click()
    expect(page.get_by_test_id("annotation-error")).to_have_text("Write the annotation first.")
    page.get_by_test_id("annotation-text").fill("E2E: subject reports a comfortable push-off")
    page.get_by_test_id("annotation-add").click()
    expect(page.get_by_test_id("annotation-error")).to_be_hidden()
    note = page.get_by_test_id("event-row").and_(page.locator("[data-kind=annotation]"))
    expect(note).to_contain_text("comfortable push-off")
    # newest first (of the clinician's and the system's: the walker's detected speed changes come any time)
    not_intent = page.locator("[data-testid=event-row]:not([data-kind=intent])")
    expect(not_intent.first).to_contain_text("comfortable push-off")
    page.wait_for_timeout(1500)  # a few more strides in the overlay for the screenshot
    page.screenshot(path=str(ARTIFACTS / "live.png"), full_page=True)

    # --- uploads: a broken MCAP is refused with the server's reason; a replay CSV becomes a trial -------
    page.goto(f"{server}/#/")
    bad = tmp_path / "broken.mcap"
    bad.write_bytes(b"this is not an MCAP file\n" * 10)
    page.get_by_test_id("upload-file").set_input_files(str(bad))
    page.get_by_test_id("upload-subject").select_option(subject_id)
    page.get_by_test_id("upload-submit").click()
    expect(page.get_by_test_id("upload-error")).to_contain_text("The file was not accepted")
    csv = _replay_csv(tmp_path / "walk_20_strides.csv")
    page.get_by_test_id("upload-file").set_input_files(str(csv))
    page.get_by_test_id("upload-submit").click()
    page.wait_for_url(re.compile(r"#/trials/\d+$"), timeout=60_000)

    # --- review: timeline, scrubbing, re-run ---------------------------------------------------------
    expect(page.get_by_test_id("trial-info")).to_contain_text("uploaded")
    expect(page.get_by_test_id("timeline").locator("canvas")).to_be_visible()
    expect(page.get_by_test_id("review-stride-count")).to_contain_text("strides", timeout=30_000)  # the trial loaded
    # a replay CSV has no centre of mass: the intent card names what is missing instead of an empty plot
    expect(page.get_by_test_id("review-intent-note")).to_contain_text("does not record com_forward_m, com_up_m")
    expect(page.get_by_test_id("review-plot-intent")).to_be_hidden()
    scrubber = page.get_by_test_id("scrubber")
    t_max = float(scrubber.get_attribute("max") or "nan")
    assert 15.0 < t_max < 40.0  # 20 strides at 1.2 m/s
    scrubber.fill(f"{t_max / 2:.2f}")
    expect(page.get_by_test_id("cursor-time")).to_have_text(f"{t_max / 2:.2f}")
    page.get_by_test_id("zoom-from").fill("5")
    page.get_by_test_id("zoom-to").fill("10")
    page.get_by_test_id("zoom-apply").click()
    expect(page.get_by_test_id("review-stride-count")).to_contain_text("strides", timeout=30_000)  # the trial loaded
    page.get_by_test_id("rerun-torque_gain").fill("1.5")
    page.get_by_test_id("rerun-submit").click()
    expect(page.get_by_test_id("rerun-ok")).to_contain_text("Overlaid: Torque gain 1.50", timeout=60_000)
    expect(page.get_by_test_id("viewer-error")).to_be_hidden()
    expect(page.get_by_test_id("download-link")).to_have_attribute("href", re.compile(r"/api/trials/\d+/download$"))

    # --- the estimator picker: the recorded stack checked; none chosen cannot run; a subset is what is sent,
    # re-run and overlaid (one legend entry per estimator); the recorded stack again sends no list ------------
    labels = {
        "hs_detector": "Heel-strike detector",
        "phase_ekf": "Phase EKF (seed 000)",
        "tbe": "Timing-based estimate",
        "hs_backup": "Heel-strike backup",
    }
    boxes = {n: page.get_by_test_id(f"rerun-estimator-{n}") for n in labels}
    recorded = ["hs_detector", "phase_ekf", "tbe"]  # the upload's stack (the backup is opt-in)
    for name, box in boxes.items():
        expect(box).to_be_enabled()
        expect(box).to_be_checked(checked=name in recorded)
        expect(page.locator(f"label[for='rerun-estimator-{name}']")).to_contain_text(labels[name])
        assert name not in page.locator(f"label[for='rerun-estimator-{name}']").inner_text()  # its label only
    entries = page.get_by_test_id("rerun-legend-entry")
    expect(entries).to_have_count(3)  # the what-if above re-ran the recorded stack
    submit = page.get_by_test_id("rerun-submit")
    for box in boxes.values():
        box.uncheck()
    expect(submit).to_be_disabled()
    expect(submit).to_have_text("Re-run: choose the estimators first")
    expect(page.get_by_test_id("rerun-estimators-error")).to_have_text("Choose at least one estimator to re-run.")
    page.get_by_test_id("rerun-mode-recorded").check()
    phase_legend = page.get_by_test_id("review-plot-phase").locator(".u-legend")
    subsets = (
        (["tbe"], "Timing-based estimate"),
        (["phase_ekf", "tbe"], "Phase EKF (seed 000) and Timing-based estimate"),
        (recorded, "3 estimators"),
    )
    for chosen, what in subsets:
        for name, box in boxes.items():
            box.set_checked(name in chosen)
        expect(page.get_by_test_id("rerun-estimators-error")).to_be_hidden()
        expect(submit).to_have_text(f"Re-run {what} with the recorded settings")
        with page.expect_request(re.compile(r"/api/trials/\d+/rerun")) as request:
            submit.click()
        # the recorded stack is not sent: the server re-runs it as recorded (what ran)
        assert request.value.post_data_json == ({} if chosen == recorded else {"estimators": chosen})
        names = [labels[n] for n in chosen]
        ran = f"Estimators: {' and '.join(filter(None, [', '.join(names[:-1]), names[-1]]))}."
        expect(page.get_by_test_id("rerun-ok")).to_contain_text(ran, timeout=60_000)
        expect(entries).to_have_count(len(chosen))
        assert [e.get_attribute("data-estimator") for e in entries.all()] == chosen
        for name, label in labels.items():  # the phase plot: each one's phase (the detector's heel strikes)
            if name in chosen:
                expect(phase_legend).to_contain_text(f"{label}, re-run")
            else:
                expect(phase_legend).not_to_contain_text(f"{label}, re-run")
        if chosen == ["phase_ekf", "tbe"]:
            page.screenshot(path=str(ARTIFACTS / "review.png"), full_page=True)
    expect(page.get_by_test_id("rerun-ok")).to_contain_text("(what ran)")
    page.get_by_test_id("rerun-clear").click()
    expect(page.get_by_test_id("rerun-legend")).to_be_hidden()
    expect(phase_legend).not_to_contain_text(", re-run")
    watched.check_clean()
