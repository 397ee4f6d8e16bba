"""The subject page's speed-change intent model card (issue #26, "the iSCI variant selectable for a subject") in a
real browser against the real server: the default shown, the iSCI variant set and shown with its source, a walk that
cannot fit refused with the server's reason, and back to the default."""

from __future__ import annotations

import pytest

from tests.e2e.accounts import call
from tests.e2e.pages import Watched

playwright_api = pytest.importorskip("playwright.sync_api")
expect = playwright_api.expect


def test_set_the_isci_variant_and_go_back_to_the_default(server: str, watched: Watched) -> None:
    page = watched.page
    subject = call(server, "POST", "/api/subjects", {"code": "ISCI1", "leg_length_m": 0.9, "mass_kg": 70.0})
    sid = subject["id"]
    watched.allow_refusal(404, rf"/api/subjects/{sid}/intent-model$")  # a reset of the default, on purpose
    page.goto(f"{server}/#/subjects/{sid}")
    card = page.get_by_test_id("intent-model-card")
    expect(card.locator("h2")).to_have_text("Speed-change intent model")
    summary = page.get_by_test_id("intent-model-summary")
    expect(summary).to_have_text("Uninjured (step length): kappa 0.242, 0.356, 0.419.")
    expect(page.get_by_test_id("intent-model-source")).to_have_text("The cohort's kappa (the default).")
    expect(page.get_by_test_id("intent-model-trial")).to_contain_text("none: the variant's default")

    page.get_by_test_id("intent-model-variant").select_option("isci")
    page.get_by_test_id("intent-model-save").click()
    expect(page.get_by_test_id("intent-model-ok")).to_have_text("Saved: the subject's next session runs it.")
    expect(summary).to_contain_text("Incomplete SCI (step length and hip-motor current): kappa 0.082, 0.055, 0.405")
    expect(summary).to_contain_text("alpha 8.61, 4.24")
    expect(page.get_by_test_id("intent-model-source")).to_contain_text("Seed 001's iSCI tuning. Set by")
    assert call(server, "GET", f"/api/subjects/{sid}/intent-model")["variant"] == "isci"

    page.get_by_test_id("intent-model-reset").click()
    expect(summary).to_have_text("Uninjured (step length): kappa 0.242, 0.356, 0.419.")
    page.get_by_test_id("intent-model-reset").click()  # the default already: the server's reason shown
    expect(page.get_by_test_id("intent-model-error")).to_contain_text("runs the default intent model already")
