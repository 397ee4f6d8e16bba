"""Issue #23, 9 ("smaller"), in a real browser against the real server: a recording in progress on the Subjects
page; the notes taken live during a trial in its review; a file uploaded twice (refused, linked, kept as a copy
when asked); the login's tries left; the Users page with accounts off; and Compare on a held-out walk by default,
the calibration walk said to be in-sample.

One simulated session (a treadmill walk streamed in real time, every channel, the thigh too) records through the
REST API a short walk and a calibration walk of 14 s; the fingerprint is fitted on the latter through the API,
as another screen would. The fixtures are ``conftest.py``'s (a server with accounts on, the browser, the
console watch), plus a second server with accounts off for the Users page.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.e2e.accounts import call, record, simulated_session
from tests.e2e.pages import Watched, watch
from tests.e2e.servers import start
from tests.walks import replay_csv

playwright_api = pytest.importorskip("playwright.sync_api")
expect = playwright_api.expect

WALK_S = 14.0  # about 12 strides at 1.0 m/s: a calibration takes 8


@pytest.fixture(scope="module")
def walker(server: str) -> Iterator[dict[str, Any]]:
    """A subject with a running simulated session (recording from its start); stopped at the module's end."""
    subject, session = simulated_session(server, "TS01", 1.0, 0.0, 300)
    try:
        yield {"subject": subject, "session": session}
    finally:
        if call(server, "GET", f"/api/sessions/{session['id']}")["state"] == "running":
            call(server, "POST", f"/api/sessions/{session['id']}/stop")


def test_a_recording_in_progress_on_the_subjects_page_and_its_live_notes_in_review(
    server: str, walker: dict[str, Any], watched: Watched
) -> None:
    page, sid, session_id = watched.page, walker["subject"]["id"], walker["session"]["id"]
    [recording] = [t for t in call(server, "GET", f"/api/trials?session_id={session_id}") if t["status"] == "recording"]
    page.goto(f"{server}/#/subjects")
    card = page.get_by_test_id("subject-row").and_(page.locator(f"[data-id='{sid}']"))
    expect(card.get_by_test_id("subject-recording")).to_have_text(f"recording now (trial {recording['id']})")
    expect(card.get_by_test_id("subject-recorded")).to_contain_text("recorded so far")
    expect(card).not_to_contain_text("nothing recorded yet")
    card.get_by_test_id("subject-details").locator("summary").click()
    live = card.get_by_test_id("trial-recording")
    expect(live).to_contain_text("recording now, ")
    expect(live).to_contain_text(" so far")
    first = live.inner_text()
    expect(live).not_to_have_text(first, timeout=15_000)  # the length so far grows (the page polls every 5 s)

    # a note taken live (another screen: the live view's note), then the trial stopped and reviewed
    call(server, "POST", f"/api/sessions/{session_id}/annotations", {"text": "subject stumbles at the belt's edge"})
    trial = call(server, "POST", f"/api/sessions/{session_id}/recording", {"action": "stop"})
    assert trial["status"] == "finished"
    # and a note added in review (another screen), before the live one in time
    call(server, "POST", f"/api/trials/{trial['id']}/annotations", {"t": 0.5, "text": "review: check the heel strikes"})
    page.goto(f"{server}/#/trials/{trial['id']}")
    rows = page.get_by_test_id("note-row")
    expect(rows).to_have_count(2, timeout=30_000)
    expect(rows.nth(0)).to_have_attribute("data-source", "review")
    expect(rows.nth(0).get_by_test_id("note-row-text")).to_have_text("review: check the heel strikes")
    live_note = rows.nth(1)
    expect(live_note).to_have_attribute("data-source", "live")
    expect(live_note.get_by_test_id("note-row-text")).to_have_text("subject stumbles at the belt's edge")
    expect(live_note.get_by_test_id("note-row-by")).to_have_text("by clinician, taken live")
    expect(live_note.get_by_test_id("note-delete")).to_have_count(0)  # the session's log: not deleted here
    expect(rows.nth(0).get_by_test_id("note-delete")).to_be_enabled()  # the clinician's own review note
    watched.check_clean()


def test_compare_defaults_to_a_held_out_walk_and_says_in_sample(
    server: str, walker: dict[str, Any], watched: Watched
) -> None:
    sid, session_id = walker["subject"]["id"], walker["session"]["id"]
    walk = record(server, session_id, WALK_S, "calibration walk")
    other = record(server, session_id, 4.0, "another walk")
    fitted = call(server, "POST", f"/api/subjects/{sid}/fingerprints", {"trial_id": walk["id"], "note": "e2e"})
    page = watched.page
    page.goto(f"{server}/#/subjects/{sid}")
    expect(page.get_by_test_id("compare-version")).to_have_value(str(fitted["id"]))
    expect(page.get_by_test_id("compare-trial").locator(f"option[value='{walk['id']}']")).to_contain_text(
        "(in-sample: v1 was fitted on it)"
    )
    with page.expect_request(re.compile(rf"/api/trials/{other['id']}/rerun\?max_points=2000$")):
        page.get_by_test_id("compare-submit").click()  # the walk picker on its default
    sample = page.get_by_test_id("compare-sample")
    expect(sample).to_have_text(
        f"Held-out walk: trial {other['id']}, not used to fit v1 (fitted on trial {walk['id']})."
    )
    expect(sample).to_have_attribute("data-sample", "held-out")
    expect(page.get_by_test_id("figure-walk-rmse-personal")).to_have_text(re.compile(r"^\d+\.\d\d deg$"))
    page.get_by_test_id("compare-trial").select_option(str(walk["id"]))
    with page.expect_request(re.compile(rf"/api/trials/{walk['id']}/rerun\?max_points=2000$")):
        page.get_by_test_id("compare-submit").click()
    expect(sample).to_have_attribute("data-sample", "in-sample")
    expect(sample).to_contain_text(f"In-sample: trial {walk['id']} is the walk v1 was fitted on, so the personalized")
    expect(page.get_by_test_id("compare-ok")).to_contain_text("(its calibration walk: in-sample)")
    watched.check_clean()


def test_a_file_uploaded_twice_is_refused_linked_and_kept_as_a_copy_when_asked(
    server: str, walker: dict[str, Any], watched: Watched, tmp_path: Path
) -> None:
    page = watched.page
    watched.allow_refusal(409, r"/api/uploads/\w+/finish$")
    csv = tmp_path / "treadmill walk.csv"
    csv.write_bytes(replay_csv())
    page.goto(f"{server}/#/")

    def upload() -> None:
        page.get_by_test_id("upload-subject").select_option(str(walker["subject"]["id"]))
        page.get_by_test_id("upload-file").set_input_files(str(csv))
        page.get_by_test_id("upload-submit").click()

    upload()
    page.wait_for_url(re.compile(r"#/trials/\d+$"), timeout=60_000)  # the first import starts the worker
    first = int(page.url.rsplit("/", 1)[1])
    page.goto(f"{server}/#/")
    upload()
    box = page.get_by_test_id("upload-duplicate-box")
    expect(box).to_be_visible(timeout=30_000)
    expect(page.get_by_test_id("upload-error")).to_contain_text(
        f"Not stored again: treadmill walk.csv was uploaded already, as trial {first} (treadmill walk.csv, "
    )
    expect(page.get_by_test_id("upload-progress-text")).to_have_text(f"already uploaded as trial {first}")
    link = page.get_by_test_id("upload-duplicate-link")
    expect(link).to_have_text(f"trial {first}")
    expect(link).to_have_attribute("href", f"#/trials/{first}")
    assert [t["id"] for t in call(server, "GET", "/api/trials") if t["name"] == csv.name] == [first]
    page.get_by_test_id("upload-keep-copy").click()
    page.wait_for_url(re.compile(r"#/trials/\d+$"), timeout=30_000)
    copy = int(page.url.rsplit("/", 1)[1])
    assert copy != first
    assert [t["id"] for t in call(server, "GET", "/api/trials") if t["name"] == csv.name] == [first, copy]
    watched.check_clean()


def test_the_login_page_says_the_tries_left(server: str, browser: Any) -> None:
    context, w = watch(browser, server, user=None)
    try:
        w.allow_refusal(401, r"/api/auth/(me|login)$")
        page = w.page
        page.goto(f"{server}/#/login")
        page.get_by_test_id("login-name").fill("nobody.at.all")  # a name that does not exist: the same answers
        error = page.get_by_test_id("login-error")
        for _ in range(3):
            page.get_by_test_id("login-password").fill("a wrong password")
            page.get_by_test_id("login-submit").click()
            expect(page.get_by_test_id("login-password")).to_have_value("")
        expect(error).to_have_text(
            "Not logged in: wrong name or password (2 tries left before logins with this name are locked)."
        )
        w.check_clean()
    finally:
        context.close()


@pytest.fixture(scope="module")
def local_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """``gaitscope serve`` with accounts off (no login), on a fresh data folder."""
    env = {**{k: v for k, v in os.environ.items() if k != "GAITSCOPE_AUTH"}, "GAITSCOPE_DEMO": "false"}
    running = start(tmp_path_factory.mktemp("gaitscope-local"), env=env)
    try:
        yield running.base
    finally:
        running.stop()


def test_the_users_page_with_accounts_off_says_so_and_how_to_turn_them_on(local_server: str, browser: Any) -> None:
    context, w = watch(browser, local_server, user=None)
    try:
        page = w.page
        page.goto(f"{local_server}/#/users")
        off = page.get_by_test_id("users-accounts-off")
        expect(off).to_contain_text("Accounts are off on this server")
        expect(off).to_contain_text("Nobody logs in")
        steps = page.get_by_test_id("users-accounts-on-steps")
        expect(steps).to_contain_text("gaitscope user add --role admin NAME")
        expect(steps).to_contain_text("GAITSCOPE_AUTH=true gaitscope serve")
        expect(page.get_by_test_id("users-none")).to_have_text("No accounts yet: add the first admin above.")
        w.check_clean()
    finally:
        context.close()
