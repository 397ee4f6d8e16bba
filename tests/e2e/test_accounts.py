"""Accounts in the browser (issue #13), against the real server with accounts on.

The login page (a wrong password refused with the server's words, failed logins that slow the guesser but lock
nobody out, then back where the user was; logout), the password change, a viewer who sees no controls, an
experimenter refused a torque gain above the subject's limit (before sending, and by the server when the limit
was lowered meanwhile), an admin's users page, and a device token shown once and revoked (the device then
refused). Screenshots of the login page at 1440x900, 1024x768 and 390x844 go to ``tests/e2e/artifacts/``.
"""

from __future__ import annotations

import json
import os
import re
import time
from collections.abc import Iterator
from typing import Any

import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from tests.e2e.accounts import PASSWORDS, Refused, client
from tests.e2e.pages import ARTIFACTS, Watched, watch
from tests.e2e.servers import start
from tests.waiting import wait_until

playwright_api = pytest.importorskip("playwright.sync_api")
expect = playwright_api.expect


SIZES = ((1440, 900), (1024, 768), (390, 844))
SIM = {"kind": "simulated", "rate_hz": 100.0, "protocol": [{"speed_m_s": 1.0, "incline_deg": 0.0, "strides": 400}]}


def _page(browser: Any, server: str, user: str | None, size: tuple[int, int] = (1024, 768)) -> Iterator[Watched]:
    context, w = watch(browser, server, user, size)
    try:
        yield w
    finally:
        context.close()


@pytest.fixture
def anonymous(browser: Any, server: str) -> Iterator[Watched]:
    """A 1024x768 page that is not logged in; the first ``me`` answers 401, on purpose."""
    for w in _page(browser, server, None):
        w.allow_refusal(401, r"/api/auth/me$")
        yield w


def _sim_session(server: str, code: str) -> tuple[int, int]:
    """A subject ``code`` with a running simulated session (stopped by the caller); (subject id, session id)."""
    clinician = client(server)
    subject = clinician.call("POST", "/api/subjects", {"code": code, "leg_length_m": 0.9, "mass_kg": 70.0})
    session = clinician.call("POST", "/api/sessions", {"subject_id": subject["id"], "source": SIM})
    return int(subject["id"]), int(session["id"])


def _stop(server: str, session_id: int) -> None:
    if client(server).call("GET", f"/api/sessions/{session_id}")["state"] == "running":
        client(server).call("POST", f"/api/sessions/{session_id}/stop")


def _add_user(server: str, name: str, role: str, password: str) -> None:
    client(server, "admin").call("POST", "/api/users", {"name": name, "role": role, "password": password})


# --- the login page ----------------------------------------------------------------------------------------
def test_login_page_refuses_a_wrong_password_then_comes_back_where_the_user_was(
    server: str, anonymous: Watched
) -> None:
    page = anonymous.page
    anonymous.allow_refusal(401, r"/api/auth/login$")
    page.goto(f"{server}/#/subjects")
    page.wait_for_url(re.compile(r"#/login\?next=%23%2Fsubjects$"))  # nobody logged in: the login page
    name = page.get_by_test_id("login-name")
    expect(name).to_be_focused()
    expect(page.get_by_test_id("user-badge")).to_be_hidden()

    # nothing typed: refused before sending; a wrong password: the server's words
    page.get_by_test_id("login-submit").click()
    expect(page.get_by_test_id("login-error")).to_have_text("Write your name.")
    name.fill("clinician")
    page.get_by_test_id("login-password").fill("not-the-password")
    page.get_by_test_id("login-submit").click()
    expect(page.get_by_test_id("login-error")).to_have_text("Not logged in: wrong name or password.")
    expect(page.get_by_test_id("login-password")).to_have_value("")
    expect(page).to_have_url(re.compile(r"#/login"))

    # the right one: back to the subjects, the badge says who and what
    page.get_by_test_id("login-password").fill(PASSWORDS["clinician"])
    page.get_by_test_id("login-password").press("Enter")
    page.wait_for_url(re.compile(r"#/subjects$"))
    expect(page.get_by_test_id("user-name")).to_have_text("clinician")
    expect(page.get_by_test_id("user-role")).to_have_text("clinician")
    expect(page.get_by_test_id("nav-users")).to_be_hidden()  # not an admin

    # log out: the login page, and every other page sends there again
    page.get_by_test_id("user-menu").locator("summary").click()
    page.get_by_test_id("menu-logout").click()
    page.wait_for_url(re.compile(r"#/login$"))
    expect(page.get_by_test_id("user-badge")).to_be_hidden()
    anonymous.allow_refusal(401, r"/api/sessions")  # the sessions page asked, was refused, went to log in
    page.goto(f"{server}/#/sessions/1")
    page.wait_for_url(re.compile(r"#/login\?next=%23%2Fsessions%2F1$"))
    anonymous.allow_refusal(401, r"/api/subjects$")
    status, _ = page.evaluate("() => fetch('/api/subjects').then(async (r) => [r.status, await r.text()])")
    assert status == 401  # the cookie is gone for the server too
    anonymous.check_clean()


def test_login_page_at_three_sizes(server: str, browser: Any) -> None:
    ARTIFACTS.mkdir(exist_ok=True)
    for width, height in SIZES:
        for w in _page(browser, server, None, (width, height)):
            w.allow_refusal(401, r"/api/auth/me$")
            page = w.page
            page.goto(f"{server}/#/login")
            expect(page.get_by_test_id("login-name")).to_be_focused()
            assert page.evaluate("() => document.documentElement.scrollWidth") <= width  # nothing off sideways
            box = page.get_by_test_id("login-submit").bounding_box()
            assert (
                box is not None and box["y"] + box["height"] <= height and box["height"] >= 44
            )  # in view, a big target
            page.screenshot(path=str(ARTIFACTS / f"login-{width}x{height}.png"), full_page=True)
            w.check_clean()


def test_failed_logins_slow_the_guesser_but_do_not_lock_the_account(server: str, anonymous: Watched) -> None:
    _add_user(server, "locked.e2e", "viewer", "locked-e2e-password")
    for _ in range(5):  # the old lockout locked an account for 15 minutes after 5 failed logins in a row
        with pytest.raises(Refused) as refused:
            client(server, "locked.e2e").log_in("a-wrong-password")
        assert refused.value.status == 401 and refused.value.detail.startswith("wrong name or password")
    assert "locked for 1 s" in refused.value.detail  # the fifth says so (tests/server/test_trust_small.py)
    time.sleep(1.1)  # after 5 failures of this address at this name, its next attempt waits 1 s
    page = anonymous.page
    page.goto(f"{server}/#/subjects")
    page.wait_for_url(re.compile(r"#/login\?next=%23%2Fsubjects$"))
    page.get_by_test_id("login-name").fill("locked.e2e")
    page.get_by_test_id("login-password").fill("locked-e2e-password")  # right, and not locked out
    page.get_by_test_id("login-submit").click()
    page.wait_for_url(re.compile(r"#/subjects$"))
    expect(page.get_by_test_id("user-name")).to_have_text("locked.e2e")
    anonymous.check_clean()


def test_change_password(server: str, anonymous: Watched) -> None:
    _add_user(server, "pw.e2e", "viewer", "first-e2e-password")
    page = anonymous.page
    page.goto(f"{server}/#/login")
    page.get_by_test_id("login-name").fill("pw.e2e")
    page.get_by_test_id("login-password").fill("first-e2e-password")
    page.get_by_test_id("login-submit").click()
    expect(page.get_by_test_id("user-name")).to_have_text("pw.e2e")
    page.get_by_test_id("user-menu").locator("summary").click()
    page.get_by_test_id("menu-password").click()
    page.wait_for_url(re.compile(r"#/account/password$"))
    fields = {k: page.get_by_test_id(f"password-{k}") for k in ("current", "new", "repeat")}
    submit, error = page.get_by_test_id("password-submit"), page.get_by_test_id("password-error")
    fields["current"].fill("first-e2e-password")
    fields["new"].fill("short")
    submit.click()
    expect(error).to_have_text("The new password needs at least 10 characters.")
    fields["new"].fill("second-e2e-password")
    fields["repeat"].fill("second-e2e-passwort")
    submit.click()
    expect(error).to_have_text("The two new passwords differ.")
    fields["repeat"].fill("second-e2e-password")
    submit.click()
    page.wait_for_url(re.compile(r"#/login$"))  # every login of the account ended, this one too
    expect(page.get_by_test_id("login-notice")).to_have_text("Password changed: log in with the new one.")
    with pytest.raises(Refused):
        client(server, "pw.e2e").log_in("first-e2e-password")
    assert client(server, "pw.e2e").log_in("second-e2e-password")["name"] == "pw.e2e"
    anonymous.check_clean()


# --- roles --------------------------------------------------------------------------------------------------
def test_a_viewer_sees_no_controls(server: str, browser: Any) -> None:
    _, sid = _sim_session(server, "VIEW1")
    try:
        for w in _page(browser, server, "viewer"):
            page = w.page
            page.goto(f"{server}/#/")
            expect(page.get_by_test_id("user-role")).to_have_text("viewer")
            for form in ("subject-form", "session-form", "upload-form"):
                card = page.get_by_test_id(form)
                expect(card.get_by_test_id("role-note")).to_be_visible()
            expect(page.get_by_test_id("session-form").get_by_test_id("role-note")).to_have_text(
                "Your role (viewer) may not run sessions and trials."
            )
            expect(page.get_by_test_id("upload-form").get_by_test_id("role-note")).to_have_text(
                "Your role (viewer) may not upload recordings."
            )
            for button in ("subject-submit", "session-submit", "upload-submit"):
                expect(page.get_by_test_id(button)).to_be_disabled()

            page.goto(f"{server}/#/sessions/{sid}")
            expect(page.get_by_test_id("live-indicator")).to_have_text("LIVE", timeout=20_000)  # they see the data
            for button in ("session-stop", "settings-apply", "recording-start", "annotation-add", "primary-apply"):
                expect(page.get_by_test_id(button)).to_be_disabled()
            expect(page.get_by_test_id("settings-card").get_by_test_id("role-note")).to_have_text(
                "Your role (viewer) may not change assistance."
            )
            expect(page.get_by_test_id("session-card").get_by_test_id("role-note")).to_have_text(
                "Your role (viewer) may not run sessions and trials."
            )
            # and the server agrees: the same request from the page is refused
            w.allow_refusal(403, rf"/api/sessions/{sid}/stop$")
            status = page.evaluate(f"() => fetch('/api/sessions/{sid}/stop', {{method: 'POST'}}).then((r) => r.status)")
            assert status == 403
            w.check_clean()
    finally:
        _stop(server, sid)


def test_an_experimenter_is_held_to_the_subjects_limits(server: str, browser: Any) -> None:
    subject_id, sid = _sim_session(server, "LIM1")
    try:
        # the clinician sets the limits on the subject page
        for w in _page(browser, server, "clinician"):
            page = w.page
            page.goto(f"{server}/#/subjects/{subject_id}")
            card = page.get_by_test_id("limits-card")
            expect(page.get_by_test_id("limits-summary")).to_contain_text("none set")
            page.get_by_test_id("limits-torque_gain").fill("1.2")
            page.get_by_test_id("limits-max_torque_Nm").fill("30")
            page.get_by_test_id("limits-intent_gain_boost").fill("0")
            page.get_by_test_id("limits-save").click()
            expect(page.get_by_test_id("limits-ok")).to_contain_text("Saved")
            expect(page.get_by_test_id("limits-summary")).to_have_text(
                "Limits: torque gain at most 1.20, maximum torque at most 30.0 N·m, intent gain boost at most 0.00 "
                "fraction of gain."
            )
            expect(card.get_by_test_id("limits-set-by")).to_contain_text("Set by clinician")
            w.check_clean()

        for w in _page(browser, server, "experimenter"):
            page = w.page
            w.allow_refusal(403, rf"/api/sessions/{sid}/settings$")
            # the subject page: the limits to read, not to change
            page.goto(f"{server}/#/subjects/{subject_id}")
            expect(page.get_by_test_id("limits-save")).to_be_disabled()
            expect(page.get_by_test_id("limits-card").get_by_test_id("role-note")).to_have_text(
                "Only a clinician or an admin sets these limits."
            )
            # the live page: the limits next to the settings; beyond them refused before sending
            page.goto(f"{server}/#/sessions/{sid}")
            expect(page.get_by_test_id("live-indicator")).to_have_text("LIVE", timeout=20_000)
            expect(page.get_by_test_id("settings-limits")).to_contain_text("torque gain at most 1.20")
            sent: list[str] = []
            page.on("request", lambda r, sent=sent: sent.append(r.url) if r.method == "PATCH" else None)
            gain = page.get_by_test_id("setting-torque_gain")
            gain.fill("1.5")
            page.get_by_test_id("settings-apply").click()
            expect(page.get_by_test_id("settings-error")).to_have_text(
                "Over the clinician's limits for this subject: torque gain 1.50 is above 1.20. Ask a clinician."
            )
            assert sent == []  # refused here, not by the server
            gain.fill("1.1")
            page.get_by_test_id("settings-apply").click()
            page.get_by_test_id("confirm-raise").click()  # a raise asks first (tests/e2e/test_trust_confirm.py)
            expect(page.get_by_test_id("settings-ok")).to_have_text("Applied: Torque gain.")
            assert len(sent) == 1
            # the clinician lowers the limit meanwhile: the page still holds the old one, the server refuses
            client(server).call(
                "PUT",
                f"/api/subjects/{subject_id}/assistance-limits",
                {"torque_gain": 1.0, "max_torque_Nm": 30.0, "intent_gain_boost": 0.0},
            )
            # past the torque rule's interval between two raises (3 s), as the server counts it
            asker, check = client(server, "experimenter"), f"/api/sessions/{sid}/settings/check"
            wait_until(
                lambda a=asker, c=check: a.call("POST", c, {"torque_gain": 1.15})["retry_after_s"] == 0,
                10.0,
                "the next raise allowed",
            )
            gain.fill("1.15")
            page.get_by_test_id("settings-apply").click()
            page.get_by_test_id("confirm-raise").click()
            expect(page.get_by_test_id("settings-error")).to_have_text(
                f"Not allowed: over the clinician's limits for subject {subject_id}: "
                "torque_gain 1.15 over the limit of 1"
            )
            # switching the estimator that drives the torque is a clinician's
            expect(page.get_by_test_id("primary-apply")).to_be_disabled()
            w.check_clean()
    finally:
        _stop(server, sid)


# --- the admin's users page --------------------------------------------------------------------------------
def test_an_admin_adds_and_manages_a_user(server: str, browser: Any) -> None:
    _add_user(server, "stuck.e2e", "viewer", "stuck-e2e-password")
    for _ in range(5):
        with pytest.raises(Refused):
            client(server, "stuck.e2e").log_in("a-wrong-password")
    for w in _page(browser, server, "admin"):
        page = w.page
        w.allow_refusal(409, r"/api/users$")
        page.goto(f"{server}/#/")
        page.get_by_test_id("nav-users").click()
        page.wait_for_url(re.compile(r"#/users$"))
        row = lambda name, page=page: page.locator(f"[data-testid=user-row][data-name='{name}']")  # noqa: E731
        expect(row("admin").get_by_test_id("user-last-login")).not_to_have_text("never")
        expect(row("viewer").get_by_test_id("user-state")).to_have_text("active")

        # add a user: a bad name refused before sending, a taken one by the server, then the new one listed
        page.get_by_test_id("user-add-name").fill("Nurse E2E")
        page.get_by_test_id("user-add-password").fill("nurse-e2e-password")
        page.get_by_test_id("user-add-submit").click()
        expect(page.get_by_test_id("user-add-error")).to_contain_text("lower case")
        page.get_by_test_id("user-add-name").fill("viewer")
        page.get_by_test_id("user-add-submit").click()
        expect(page.get_by_test_id("user-add-error")).to_contain_text("Refused")
        page.get_by_test_id("user-add-name").fill("nurse.e2e")
        page.get_by_test_id("user-add-role").select_option("experimenter")
        page.get_by_test_id("user-add-password").fill("nurse-e2e-password")
        page.get_by_test_id("user-add-submit").click()
        expect(page.get_by_test_id("user-add-ok")).to_have_text("Added experimenter nurse.e2e.")
        expect(row("nurse.e2e")).to_have_attribute("data-role", "experimenter")
        expect(row("nurse.e2e").get_by_test_id("user-last-login")).to_have_text("never")
        assert client(server, "nurse.e2e").log_in("nurse-e2e-password")["role"] == "experimenter"

        # a role change; disable (the login refused), enable again
        row("nurse.e2e").get_by_test_id("user-role").select_option("viewer")
        row("nurse.e2e").get_by_test_id("user-role-apply").click()
        expect(row("nurse.e2e")).to_have_attribute("data-role", "viewer")
        row("nurse.e2e").get_by_test_id("user-disable").click()
        expect(row("nurse.e2e").get_by_test_id("user-state")).to_have_text("disabled")
        with pytest.raises(Refused) as refused:
            client(server, "nurse.e2e").log_in("nurse-e2e-password")
        assert "disabled" in str(refused.value.detail)
        row("nurse.e2e").get_by_test_id("user-enable").click()
        expect(row("nurse.e2e").get_by_test_id("user-state")).to_have_text("active")

        # a user with failed logins: unlocked (the count forgotten); a new password set for them
        expect(row("stuck.e2e").get_by_test_id("user-state")).to_contain_text("5 failed logins")
        row("stuck.e2e").get_by_test_id("user-unlock").click()
        expect(row("stuck.e2e").get_by_test_id("user-state")).to_have_text("active")
        row("stuck.e2e").get_by_test_id("user-reset-password").fill("fresh-e2e-password")
        row("stuck.e2e").get_by_test_id("user-reset-apply").click()
        expect(row("stuck.e2e").get_by_test_id("user-row-ok")).to_contain_text("New password set for stuck.e2e")
        assert client(server, "stuck.e2e").log_in("fresh-e2e-password")["name"] == "stuck.e2e"
        w.check_clean()


# --- device credentials -------------------------------------------------------------------------------------
def _device_answers(base: str, session_id: int, token: str | None) -> dict[str, Any]:
    """Connects as the session's device with ``token``, sends one frame and returns the server's answer."""
    url = base.replace("http://", "ws://") + f"/ws/devices/{session_id}"
    headers = {"Authorization": f"Bearer {token}"} if token else None
    with connect(url, additional_headers=headers, open_timeout=10) as ws:
        ws.send(json.dumps({"seq": 0, "t": 0.0, "foot_angle_deg": 0.0, "shank_angle_deg": 0.0}))
        answer: dict[str, Any] = json.loads(ws.recv(timeout=10))
        return answer


def test_a_device_token_is_shown_once_and_revoked(server: str, browser: Any) -> None:
    clinician = client(server)
    subject = clinician.call("POST", "/api/subjects", {"code": "DEV1", "leg_length_m": 0.9, "mass_kg": 70.0})
    source = {"kind": "device", "rate_hz": 100.0, "channels": ["foot_angle_deg", "shank_angle_deg"]}
    sid = clinician.call("POST", "/api/sessions", {"subject_id": subject["id"], "source": source})["id"]
    try:
        for w in _page(browser, server, "clinician"):
            page = w.page
            page.context.grant_permissions(["clipboard-read", "clipboard-write"])
            page.goto(f"{server}/#/sessions/{sid}")
            card = page.get_by_test_id("device-credentials-card")
            expect(card).to_be_visible()
            expect(card.get_by_test_id("token-none")).to_be_visible()
            page.get_by_test_id("token-issue").click()
            value = page.get_by_test_id("token-value")
            expect(value).to_have_text(re.compile(r"^\S{20,}$"))
            token = value.text_content() or ""
            expect(page.get_by_test_id("token-warning")).to_contain_text("it will not be shown again")
            page.get_by_test_id("token-copy").click()
            expect(page.get_by_test_id("token-copied")).to_have_text("Copied.")
            assert page.evaluate("() => navigator.clipboard.readText()") == token
            rows = card.get_by_test_id("token-row")
            expect(rows).to_have_count(1)
            prefix = (rows.get_by_test_id("token-prefix").text_content() or "").rstrip("…")
            assert prefix and token.startswith(prefix) and prefix != token
            expect(rows.get_by_test_id("token-state")).to_have_text("in use")

            # the device streams with it; without a token it is refused
            assert _device_answers(server, sid, token)["type"]
            with pytest.raises(InvalidStatus) as refused:
                _device_answers(server, sid, None)
            assert refused.value.response.status_code == 403

            # shown once: gone once hidden, and not there after a reload
            page.get_by_test_id("token-hide").click()
            expect(page.get_by_test_id("token-fresh")).to_be_hidden()
            page.reload()
            expect(card.get_by_test_id("token-row")).to_have_count(1)
            assert token not in page.content()

            # revoke (two taps): listed as revoked, and the device is refused
            revoke = card.get_by_test_id("token-revoke")
            # the two taps in one turn of the page's event loop: the 4 s arming cannot lapse between them on a
            # busy machine, and the first tap's label is read before the second
            armed = revoke.evaluate("b => { b.click(); const label = b.textContent; b.click(); return label; }")
            assert armed == "Tap again to revoke"
            expect(rows.get_by_test_id("token-state")).to_have_text(
                re.compile(r"^revoked .+ by clinician$"), timeout=15_000
            )
            expect(card.get_by_test_id("token-revoke-error")).to_be_hidden()
            expect(card.get_by_test_id("token-revoke")).to_have_count(0)
            with pytest.raises(InvalidStatus) as refused:
                _device_answers(server, sid, token)
            assert refused.value.response.status_code == 403
            w.check_clean()
    finally:
        _stop(server, sid)


# --- accounts off (the README's default): nobody logs in ------------------------------------------------------
@pytest.fixture(scope="module")
def local_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """``gaitscope serve`` as the README starts it: loopback, accounts off."""
    data = tmp_path_factory.mktemp("gaitscope-local")
    env = {k: v for k, v in os.environ.items() if k != "GAITSCOPE_AUTH"}
    running = start(data, env)
    try:
        yield running.base
    finally:
        running.stop()


def test_with_accounts_off_nobody_logs_in(local_server: str, browser: Any) -> None:
    for w in _page(browser, local_server, None):
        page = w.page
        page.goto(f"{local_server}/#/subjects")
        expect(page.get_by_test_id("user-name")).to_have_text("local (no login: this computer only)")
        expect(page.get_by_test_id("menu-logout")).to_have_count(0)
        expect(page.get_by_test_id("nav-users")).to_be_visible()  # local is the admin
        expect(page).to_have_url(re.compile(r"#/subjects$"))
        page.goto(f"{local_server}/#/login")
        expect(page.get_by_test_id("login-done")).to_contain_text("Accounts are off on this server: nobody logs in.")
        # state changes need no CSRF token without a login
        page.goto(f"{local_server}/#/")
        page.get_by_test_id("subject-code").fill("LOCAL1")
        page.get_by_test_id("subject-submit").click()
        expect(page.get_by_test_id("subject-ok")).to_contain_text("Subject LOCAL1 created")
        w.check_clean()
