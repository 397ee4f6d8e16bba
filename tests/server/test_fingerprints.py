"""A subject's personalized gait model through the real API: calibrate from a recorded walk, compare,
promote (live sessions told, fp_ls takes it), roll back, export and import; bad walks refused with why."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from gaitscope.sessions.synth.cohort import CohortSpec, make_subjects
from tests.server.apps import recorded, subject
from tests.walks import walk_frames

RATE_HZ = 100.0


def test_calibrate_compare_promote_and_roll_back(client: TestClient) -> None:
    sid = subject(client)
    tid, _ = recorded(client, sid, walk_frames())
    listing = client.get(f"/api/subjects/{sid}/fingerprints").json()
    assert listing["components"] == 3 and listing["active"] is None and listing["versions"] == []
    assert len(listing["cohort"]) == 10 and all(len(p["fingerprint"]) == 3 for p in listing["cohort"])

    r = client.post(f"/api/subjects/{sid}/fingerprints", json={"trial_id": tid, "actor": "local", "note": "first"})
    assert r.status_code == 201, r.text
    v1 = r.json()
    assert v1["state"] == "candidate" and v1["version"] == 1 and v1["created_by"] == "local"
    assert v1["strides_used"] >= 15 and v1["stride_length_source"] == "belt speed"
    assert v1["fit_rmse_personal_deg"] < v1["fit_rmse_avg_deg"]
    # the subject's fingerprint is the cohort subject's own, near its training one (same person, new walk)
    own = listing["cohort"][make_subjects(CohortSpec())[3].code == "VC04" and 3]["fingerprint"]
    assert np.linalg.norm(np.array(v1["fingerprint"]) - own) < 1.5

    # compare before promoting: the candidate re-run beside the average model
    r = client.post(
        f"/api/trials/{tid}/rerun?max_points=20000",
        json={"estimators": ["fp_avg", "fp_ls"], "personalization_id": v1["id"], "settings": {"primary": "fp_ls"}},
    )
    assert r.status_code == 200, r.text
    series = r.json()
    assert len(series["fp_ls.phase"]) == len(series["fp_avg.phase"]) > 1000
    assert series["phase"] == series["fp_ls.phase"]  # the personalized filter drove this re-run

    # promote: a running session of the subject is told, its fp_ls takes it
    before = client.get(f"/api/subjects/{sid}/fingerprints").json()
    assert before["active"] is None
    r = client.post(f"/api/subjects/{sid}/fingerprints/{v1['id']}/promote", json={"actor": "local", "reason": "fits"})
    assert r.status_code == 200 and r.json()["state"] == "active" and r.json()["promoted_by"] == "local"
    tid2, runtime = recorded(client, sid, walk_frames(8, subject=3))
    assert "fp_ls" in runtime.estimator.stack.names and runtime.fingerprint == v1["fingerprint"]
    v2 = client.post(f"/api/subjects/{sid}/fingerprints", json={"trial_id": tid2}).json()
    assert v2["version"] == 2
    client.app.state.ctx.manager.runtimes[runtime.session.id] = runtime  # type: ignore[attr-defined]
    try:
        r = client.post(f"/api/subjects/{sid}/fingerprints/{v2['id']}/promote", json={"actor": "local"})
        assert r.status_code == 200, r.text
        texts = [e.text for e in client.app.state.ctx.store.list_events(runtime.session.id)]  # type: ignore[attr-defined]
        assert any("v2 promoted by local; fp_ls takes it at the next heel strike" in t for t in texts), texts
        # while its torque follows fp_ls, a promotion or a roll back changes what drives it: asked first (#23)
        runtime.estimator.stack.set_primary("fp_ls")
        for url, body in ((f"fingerprints/{v1['id']}/promote", {}), ("fingerprints/rollback", {})):
            r = client.post(f"/api/subjects/{sid}/{url}", json=body)
            assert r.status_code == 409, r.text
            assert f"running session {runtime.session.id} follows the personalized filter (fp_ls)" in r.json()["detail"]
            assert "confirm" in r.json()["detail"]
        assert client.get(f"/api/subjects/{sid}/fingerprints").json()["active"]["version"] == 2  # nothing changed
        r = client.post(f"/api/subjects/{sid}/fingerprints/{v2['id']}/promote", json={"confirm": True})
        assert r.status_code == 200, r.text
        runtime.estimator.stack.set_primary("phase_ekf")
    finally:
        del client.app.state.ctx.manager.runtimes[runtime.session.id]  # type: ignore[attr-defined]
    listing = client.get(f"/api/subjects/{sid}/fingerprints").json()
    assert listing["active"]["version"] == 2 and [v["state"] for v in listing["versions"]] == ["active", "retired"]

    # roll back: v1 again, then the average model, then nothing to roll back
    r = client.post(f"/api/subjects/{sid}/fingerprints/rollback", json={"actor": "local", "reason": "worse"})
    assert r.status_code == 200 and r.json()["active"]["version"] == 1
    v2_now = next(v for v in r.json()["versions"] if v["version"] == 2)
    assert v2_now["state"] == "retired" and v2_now["retired_by"] == "local" and v2_now["retired_utc"]
    r = client.post(f"/api/subjects/{sid}/fingerprints/rollback", json={})
    assert r.status_code == 200 and r.json()["active"] is None
    r = client.post(f"/api/subjects/{sid}/fingerprints/rollback", json={})
    assert r.status_code == 409 and "no active personalization" in r.json()["detail"]


def test_export_and_import_move_a_fingerprint_and_refuse_another_map(client: TestClient) -> None:
    sid = subject(client)
    tid, _ = recorded(client, sid, walk_frames(12))
    v1 = client.post(f"/api/subjects/{sid}/fingerprints", json={"trial_id": tid}).json()
    r = client.get(f"/api/subjects/{sid}/fingerprints/{v1['id']}/export")
    assert r.status_code == 200 and "attachment" in r.headers["content-disposition"]
    exported: dict[str, Any] = r.json()
    other = subject(client, "P02")
    r = client.post(f"/api/subjects/{other}/fingerprints/import", json=exported)
    assert r.status_code == 201, r.text
    assert r.json()["fingerprint"] == v1["fingerprint"] and r.json()["source_trial_id"] is None
    r = client.post(f"/api/subjects/{other}/fingerprints/import", json={**exported, "model_sha256": "0" * 64})
    assert r.status_code == 422 and "another version of model" in r.json()["detail"]
    r = client.post(f"/api/subjects/{other}/fingerprints/import", json={**exported, "fingerprint": [1.0, 2.0]})
    assert r.status_code == 422 and "2 components" in r.json()["detail"]
    r = client.post(f"/api/subjects/{other}/fingerprints/import", json={**exported, "fingerprint": [1e9, 0, 0]})
    assert r.status_code == 422


@pytest.mark.parametrize(
    ("spoil", "why"),
    [
        (lambda f: f.model_copy(update={"thigh_angle_deg": None, "thigh_vel_dps": None}), "no thigh angle"),
        # a dropout in every stride (100 samples a stride at 1 m/s): each one left out, counted
        (lambda f: f.model_copy(update={"thigh_angle_deg": math.nan}) if f.seq % 97 < 4 else f, "thigh angle missing"),
    ],
)
def test_a_walk_that_cannot_calibrate_is_refused_with_why_and_nothing_is_stored(
    client: TestClient, spoil: Any, why: str
) -> None:
    sid = subject(client)
    frames = [spoil(f) for f in walk_frames(12)]
    tid, _ = recorded(client, sid, frames)
    r = client.post(f"/api/subjects/{sid}/fingerprints", json={"trial_id": tid})
    assert r.status_code == 422 and why in r.json()["detail"], r.text
    assert client.get(f"/api/subjects/{sid}/fingerprints").json()["versions"] == []


def test_too_short_a_walk_and_a_trial_of_someone_else_are_refused(client: TestClient) -> None:
    sid = subject(client)
    tid, _ = recorded(client, sid, walk_frames(4))
    r = client.post(f"/api/subjects/{sid}/fingerprints", json={"trial_id": tid})
    assert r.status_code == 422 and "usable strides" in r.json()["detail"] and "at least 8" in r.json()["detail"]
    other = subject(client, "P02")
    r = client.post(f"/api/subjects/{other}/fingerprints", json={"trial_id": tid})
    assert r.status_code == 422 and "not of subject" in r.json()["detail"]
    assert client.post(f"/api/subjects/{sid}/fingerprints", json={"trial_id": 999}).status_code == 404
    assert client.post(f"/api/subjects/{sid}/fingerprints", json={"trial_id": tid, "actor": ""}).status_code == 422
