"""The subject page (``#/subjects/{id}``) in a real browser against the real server: a clinician personalizes
a subject's gait model (seed 004's fingerprints).

The walks come from the running server itself: a simulated session (a virtual-cohort subject on a treadmill;
the simulated sensors send every channel, the thigh angle included) records, through the REST API, a walk of
3 s (too few strides) and one of 16 s (about 14 strides). The session keeps running, so the page shows its
live online fingerprint. In the browser: the short walk is refused with the server's reason, the long one
fits a candidate, which is compared with the average model (both re-run and overlaid), promoted, rolled back
to the average model; an export is imported (and a tampered one refused). Then a calibration walk is recorded
from the page itself ("record a calibration walk now"): cancelled, abandoned by leaving the page, walked to the
end and fitted, and cut short by the session ending (the module's last step). The fixtures are
``conftest.py``'s (the same server, browser and console watch); screenshots go to
``tests/e2e/artifacts/subject.png`` and ``subject-walk.png`` (the Calibrate card mid-walk).
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.e2e.accounts import call, log_in, record
from tests.e2e.pages import ARTIFACTS, Watched

playwright_api = pytest.importorskip("playwright.sync_api")
expect = playwright_api.expect

SHORT_S = 3.0  # about 2 strides: fewer than the 8 a calibration needs
WALK_S = 16.0  # about 14 strides at 1.0 m/s


@pytest.fixture(scope="module")
def walks(server: str) -> Iterator[dict[str, Any]]:
    """A subject with a running simulated session of theirs, which recorded a short and a calibration walk."""
    subject = call(server, "POST", "/api/subjects", {"code": "FP01", "leg_length_m": 0.9, "mass_kg": 70.0})
    source = {
        "kind": "simulated",
        "rate_hz": 100.0,  # half the default: a lighter re-run, strides as good
        "protocol": [{"speed_m_s": 1.0, "incline_deg": 0.0, "strides": 300}],
    }
    session = call(server, "POST", "/api/sessions", {"subject_id": subject["id"], "source": source})
    assert session["state"] == "running"
    try:
        short = record(server, session["id"], SHORT_S, "standing start")
        walk = record(server, session["id"], WALK_S, "calibration walk")
        assert walk["duration_s"] > WALK_S - 2, walk
        yield {"subject": subject, "session": session, "short": short, "walk": walk}
    finally:
        if call(server, "GET", f"/api/sessions/{session['id']}")["state"] == "running":  # the last test stops it
            call(server, "POST", f"/api/sessions/{session['id']}/stop")


def _recording(base: str, session_id: int) -> list[dict[str, Any]]:
    """The session's trials still recording."""
    trials: list[dict[str, Any]] = call(base, "GET", f"/api/trials?session_id={session_id}")
    return [t for t in trials if t["status"] == "recording"]


def _rmse(text: str | None) -> tuple[float, float]:
    m = re.fullmatch(r"(\d+\.\d+) → (\d+\.\d+)", (text or "").strip())
    assert m, f"not 'average → personal': {text!r}"
    return float(m[1]), float(m[2])


def test_calibrate_compare_promote_and_roll_back(
    server: str, walks: dict[str, Any], watched: Watched, tmp_path: Path
) -> None:
    page = watched.page
    sid, session_id = walks["subject"]["id"], walks["session"]["id"]
    short, walk = walks["short"], walks["walk"]
    watched.allow_refusal(422, rf"/api/subjects/{sid}/fingerprints$")  # the short walk, refused on purpose
    watched.allow_refusal(422, rf"/api/subjects/{sid}/fingerprints/import$")  # a tampered file

    # --- from the sessions list to the subject's page ----------------------------------------------------
    page.goto(f"{server}/#/")
    page.get_by_test_id(f"subject-link-{sid}").first.click()
    page.wait_for_url(re.compile(rf"#/subjects/{sid}$"))
    expect(page.get_by_test_id("subject-title")).to_have_text("Subject FP01")
    expect(page.get_by_test_id("subject-leg")).to_have_text("Leg length 0.90 m")
    expect(page.get_by_test_id("subject-mass")).to_have_text("mass 70.0 kg")
    expect(page.get_by_test_id("active-model")).to_contain_text("the average model is in use")
    expect(page.get_by_test_id("versions-table")).to_contain_text("No personalized model yet")
    expect(page.get_by_test_id("rollback")).to_be_disabled()

    # --- where the subject sits: the training subjects, and the running session's online fingerprint ------
    expect(page.get_by_test_id("fp-point-cohort")).to_have_count(10)
    live = page.get_by_test_id("fp-point-live")
    expect(live).to_have_count(1, timeout=20_000)
    expect(page.get_by_test_id("fp-live-text")).to_contain_text(f"Live, session {session_id}")
    first = live.get_attribute("data-g1")
    expect(live).not_to_have_attribute("data-g1", first or "", timeout=10_000)  # it moves

    # --- calibrate: the short walk refused with the server's reason, the long one fits a candidate ----------
    calibrate = page.get_by_test_id("calibrate-submit")
    page.get_by_test_id("calibrate-trial").select_option(str(short["id"]))
    calibrate.click()
    expect(page.get_by_test_id("calibrate-error")).to_contain_text("Not accepted: trial")
    expect(page.get_by_test_id("calibrate-error")).to_contain_text("walk at least 8 steady strides")
    expect(page.get_by_test_id("calibrate-error")).to_have_attribute("role", "alert")
    expect(calibrate).to_be_enabled()

    held: list[Any] = []  # the fit's request, held until the busy state has been seen (the page's polls pass)
    fit_url = re.compile(rf"/api/subjects/{sid}/fingerprints$")
    page.route(fit_url, lambda route: held.append(route) if route.request.method == "POST" else route.continue_())
    page.get_by_test_id("calibrate-trial").select_option(str(walk["id"]))
    page.get_by_test_id("calibrate-note").fill("E2E treadmill 1.0 m/s")
    calibrate.click()
    expect(calibrate).to_be_disabled()
    expect(calibrate).to_have_text("Fitting…")
    expect(page.get_by_test_id("calibrate-busy")).to_be_visible()
    expect(page.get_by_test_id("calibrate-error")).to_be_hidden()
    for _ in range(100):
        if held:
            break
        page.wait_for_timeout(50)
    assert len(held) == 1 and held[0].request.post_data_json == {
        "trial_id": walk["id"],
        "model": "default",
        "note": "E2E treadmill 1.0 m/s",
    }
    held[0].continue_()
    page.unroute(fit_url)
    expect(page.get_by_test_id("calibrate-ok")).to_contain_text(f"Candidate v1 fitted from trial {walk['id']}")
    expect(calibrate).to_have_text("Fit fingerprint")
    expect(calibrate).to_be_enabled()
    expect(page.get_by_test_id("calibrate-busy")).to_be_hidden()
    row = page.get_by_test_id("version-row").and_(page.locator("[data-version='1']"))
    expect(row).to_have_attribute("data-state", "candidate")
    expect(row.get_by_test_id("version-state")).to_have_text("candidate")
    expect(row).to_contain_text("E2E treadmill 1.0 m/s")
    expect(row).to_contain_text(f"Trial {walk['id']}")
    avg, personal = _rmse(row.get_by_test_id("version-rmse").text_content())
    assert 0 < personal < avg
    g = r"-?\d+\.\d\d"
    expect(row.get_by_test_id("version-fingerprint")).to_have_text(re.compile(rf"^g1 {g} · g2 {g} · g3 {g}$"))
    expect(page.get_by_test_id("fp-point-version")).to_have_attribute("data-state", "candidate")
    listing = call(server, "GET", f"/api/subjects/{sid}/fingerprints")
    pid = listing["versions"][0]["id"]

    # --- compare: a held-out walk (the short one: v1 was fitted on the other) re-run with the average and the
    # candidate's model, overlaid; then the calibration walk itself, said to be in-sample (issue #23, 9) -----------
    with page.expect_request(re.compile(rf"/api/trials/{short['id']}/rerun\?max_points=2000$")) as rerun:
        row.get_by_test_id("compare").click()
    assert rerun.value.post_data_json == {"estimators": ["fp_avg", "fp_ls"], "personalization_id": pid}
    expect(page.get_by_test_id("compare-sample")).to_have_text(
        f"Held-out walk: trial {short['id']}, not used to fit v1 (fitted on trial {walk['id']})."
    )
    expect(page.get_by_test_id("compare-ok")).to_contain_text(f"Trial {short['id']} re-run")
    page.get_by_test_id("compare-trial").select_option(str(walk["id"]))
    expect(page.get_by_test_id("compare-trial").locator("option:checked")).to_contain_text(
        "(in-sample: v1 was fitted on it)"
    )
    with page.expect_request(re.compile(rf"/api/trials/{walk['id']}/rerun\?max_points=2000$")):
        page.get_by_test_id("compare-submit").click()
    expect(page.get_by_test_id("compare-sample")).to_contain_text(
        f"In-sample: trial {walk['id']} is the walk v1 was fitted on"
    )
    compared = f"Trial {walk['id']} re-run with the average model and v1's fingerprint"
    expect(page.get_by_test_id("compare-ok")).to_contain_text(compared)
    for key in ("phase", "stride", "thigh"):
        plot = page.get_by_test_id(f"compare-plot-{key}")
        expect(plot.locator("canvas")).to_be_visible()
        expect(plot.locator(".u-legend")).to_contain_text("average model")
        expect(plot.locator(".u-legend")).to_contain_text("personalized v1")
    expect(page.get_by_test_id("compare-plot-thigh").locator(".u-legend")).to_contain_text("measured")
    expect(page.get_by_test_id("figure-rmse-avg")).to_have_text(f"{avg:.2f} deg")
    expect(page.get_by_test_id("figure-rmse-personal")).to_contain_text(f"{personal:.2f} deg (")
    expect(page.get_by_test_id("compare-error")).to_be_hidden()
    ARTIFACTS.mkdir(exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / "subject.png"), full_page=True)

    # --- promote, with the confirm step and a reason -----------------------------------------------------------
    row.get_by_test_id("promote").click()
    expect(page.get_by_test_id("confirm-text")).to_contain_text("Promote v1 (candidate")
    page.get_by_test_id("change-reason").fill("tracks her thigh better")
    page.get_by_test_id("confirm-apply").click()
    expect(page.get_by_test_id("models-status")).to_have_text(
        "v1 promoted by clinician (tracks her thigh better): it is FP01's model now."
    )
    expect(page.get_by_test_id("confirm")).to_be_hidden()
    expect(row).to_have_attribute("data-state", "active")
    expect(row.get_by_test_id("version-state")).to_have_text("ACTIVE")
    expect(row.get_by_test_id("promote")).to_have_count(0)
    expect(page.get_by_test_id("active-model")).to_contain_text("v1 is in use, promoted by clinician")
    expect(page.get_by_test_id("fp-point-version")).to_have_attribute("data-state", "active")
    events = [e["text"] for e in call(server, "GET", f"/api/sessions/{session_id}/events")]
    assert any("v1 promoted by clinician (tracks her thigh better)" in t for t in events), events

    # --- an experimenter may not roll back (the button says why); the admin does: the average model again -------
    for user in ("experimenter", "admin"):
        log_in(page.context, server, user)  # the same browser, another login
        page.reload()
        expect(page.get_by_test_id("active-model")).to_contain_text("v1 is in use")
        if user == "experimenter":
            expect(page.get_by_test_id("rollback")).to_be_disabled()
            expect(page.get_by_test_id("rollback")).to_have_attribute(
                "title", "Your role (experimenter) may not promote or roll back personalized models."
            )
    page.get_by_test_id("rollback").click()
    expect(page.get_by_test_id("confirm-text")).to_contain_text("Roll back v1?")
    page.get_by_test_id("confirm-apply").click()
    expect(page.get_by_test_id("models-status")).to_have_text(
        "v1 rolled back by admin: the average model is in use again."
    )
    expect(page.get_by_test_id("active-model")).to_contain_text("the average model is in use")
    expect(row).to_have_attribute("data-state", "retired")
    expect(page.get_by_test_id("rollback")).to_be_disabled()
    assert call(server, "GET", f"/api/subjects/{sid}/fingerprints")["active"] is None

    # --- export, import: a tampered file refused with the server's reason, the export taken as v2 -------------
    export = row.get_by_test_id("export")
    expect(export).to_have_attribute("href", f"/api/subjects/{sid}/fingerprints/{pid}/export")
    exported = call(server, "GET", f"/api/subjects/{sid}/fingerprints/{pid}/export")
    tampered = tmp_path / "tampered.json"
    tampered.write_text(json.dumps({**exported, "model_sha256": "0" * 64}))
    good = tmp_path / "FP01-fingerprint-v1.json"
    good.write_text(json.dumps(exported))
    page.get_by_text("Import a version exported from another gaitscope").click()
    page.get_by_test_id("import-file").set_input_files(str(tampered))
    page.get_by_test_id("import-submit").click()
    expect(page.get_by_test_id("import-error")).to_contain_text("another version of model 'default'")
    page.get_by_test_id("import-file").set_input_files(str(good))
    page.get_by_test_id("import-submit").click()
    expect(page.get_by_test_id("import-error")).to_be_hidden()
    expect(page.get_by_test_id("models-status")).to_contain_text("Imported as candidate v2")
    imported = page.get_by_test_id("version-row").and_(page.locator("[data-version='2']"))
    expect(imported).to_have_attribute("data-state", "candidate")
    expect(imported).to_contain_text("imported")
    watched.check_clean()


def test_record_a_calibration_walk_now(server: str, walks: dict[str, Any], watched: Watched) -> None:
    """The Calibrate card's walk on the running session: it finishes a recording under way (another screen's),
    shows its progress, stops on Cancel and when the page goes, fits a candidate at its end, and says so when
    the session ends during a walk. Runs after the test above (v1 retired, v2 imported): this walk is v3."""
    page = watched.page
    sid, session_id = walks["subject"]["id"], walks["session"]["id"]
    recording = f"/api/sessions/{session_id}/recording"
    other = call(server, "POST", recording, {"action": "start", "name": "other screen"})
    page.goto(f"{server}/#/subjects/{sid}")
    note = page.get_by_test_id("walk-note")
    expect(note).to_contain_text(f"Session {session_id} is running")
    expect(note).to_contain_text(f"It is recording “other screen” (trial {other['id']})")
    duration = page.get_by_test_id("walk-duration")
    expect(duration).to_have_value("30")
    assert duration.locator("option").all_text_contents() == ["20 s", "30 s", "60 s"]
    duration.select_option("20")
    start = page.get_by_role("button", name="Record a calibration walk now")
    bar = page.get_by_role("progressbar", name="Calibration walk recorded")
    left = page.get_by_test_id("walk-left")

    def walk_started() -> dict[str, Any]:
        """A click on the button: the walk's trial recording, its bar moving; the trial."""
        start.click()
        expect(bar).to_have_attribute("aria-valuemax", "20")
        expect(bar).to_have_attribute("aria-valuenow", re.compile(r"^([1-9]|1\d)$"))  # a second or more
        expect(left).to_have_text(re.compile(r"^\d+ s of 20 s · \d+ s left$"))
        (trial,) = _recording(server, session_id)
        # trial names are unique within a session: the fixture's "calibration walk" is taken, so "... 2", ...
        assert re.fullmatch(r"calibration walk( \d+)?", trial["name"]) and trial["id"] > other["id"], trial
        return trial

    # --- Cancel: the other screen's recording was finished (and kept), this one stopped, nothing fitted ---------
    cancelled = walk_started()
    assert call(server, "GET", f"/api/trials/{other['id']}")["status"] == "finished"
    expect(note).to_contain_text(f"Recording trial {cancelled['id']} (“{cancelled['name']}”) on session {session_id}")
    expect(page.get_by_test_id("calibrate-submit")).to_be_disabled()  # one calibration at a time
    page.get_by_test_id("walk-cancel").click()
    expect(page.get_by_test_id("calibrate-ok")).to_contain_text(
        f"its recording stopped (kept as trial {cancelled['id']}); nothing was fitted"
    )
    expect(bar).to_be_hidden()
    expect(start).to_be_enabled()
    assert _recording(server, session_id) == []
    assert call(server, "GET", f"/api/trials/{cancelled['id']}")["status"] == "finished"
    assert len(call(server, "GET", f"/api/subjects/{sid}/fingerprints")["versions"]) == 2

    # --- leaving the page mid-walk stops the recording -------------------------------------------------------
    walk_started()
    page.get_by_role("link", name="← Sessions").click()
    page.wait_for_url(re.compile(r"#/$"))
    for _ in range(50):
        if not _recording(server, session_id):
            break
        page.wait_for_timeout(100)
    assert _recording(server, session_id) == [], "the walk still records after the page went"

    # --- a walk to its end: the bar fills, the walk is fitted at once ------------------------------------------
    page.goto(f"{server}/#/subjects/{sid}")
    page.get_by_test_id("calibrate-note").fill("walked now")
    expect(note).to_contain_text(f"Session {session_id} is running")
    duration.select_option("20")
    walked = walk_started()
    expect(bar).to_have_attribute("aria-valuenow", re.compile(r"^1\d$"), timeout=15_000)  # ten seconds or more
    ARTIFACTS.mkdir(exist_ok=True)
    page.get_by_test_id("calibrate-card").screenshot(path=str(ARTIFACTS / "subject-walk.png"))
    ok = page.get_by_test_id("calibrate-ok")
    expect(ok).to_contain_text(f"Candidate v3 fitted from trial {walked['id']}", timeout=20_000)
    expect(page.get_by_test_id("calibrate-error")).to_be_hidden()
    expect(bar).to_be_hidden()
    expect(page.get_by_test_id("calibrate-trial")).to_have_value(str(walked["id"]))
    row = page.get_by_test_id("version-row").and_(page.locator("[data-version='3']"))
    expect(row).to_have_attribute("data-state", "candidate")
    expect(row).to_contain_text(f"Trial {walked['id']}")
    expect(row).to_contain_text("walked now")
    trial = call(server, "GET", f"/api/trials/{walked['id']}")
    assert trial["status"] == "finished" and 19.0 < trial["duration_s"] < 23.0, trial
    assert _recording(server, session_id) == []

    # --- the session ends during a walk: said, what was recorded offered, nothing fitted (the module's end) ----
    cut = walk_started()
    call(server, "POST", f"/api/sessions/{session_id}/stop")
    error = page.get_by_test_id("calibrate-error")
    expect(error).to_have_text(re.compile(r"^The calibration walk was cut short \(\d+\.\d s of 20 s recorded\): "))
    expect(error).to_contain_text(f"session {session_id} ended. Nothing was fitted")
    expect(error).to_contain_text(f"kept as trial {cut['id']}")
    expect(page.get_by_test_id("calibrate-trial")).to_have_value(str(cut["id"]))
    expect(bar).to_be_hidden()
    assert len(call(server, "GET", f"/api/subjects/{sid}/fingerprints")["versions"]) == 3
    watched.check_clean()
