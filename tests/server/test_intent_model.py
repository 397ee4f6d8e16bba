"""A subject's speed-change intent model through the real API: fitted on a recorded walk with speed changes, or the
iSCI variant's default; run by the subject's next session and written into its recordings; refusals say why."""

from __future__ import annotations

import functools
import json

import numpy as np
from fastapi.testclient import TestClient

from gaitscope.estimators.intent import COHORT, ISCI
from gaitscope.estimators.intent_estimator import IntentEstimator
from gaitscope.sessions.formats.mcap_io import metadata_of
from gaitscope.sessions.formats.recording import METADATA_NAME
from gaitscope.sessions.live.sources import frames_from_table
from gaitscope.sessions.personalization.intent_model import INTENT_MODEL_KEY, from_metadata
from gaitscope.sessions.schema import SensorFrame
from gaitscope.sessions.synth.cohort import CohortSpec, make_subjects
from gaitscope.sessions.synth.intent_walks import IntentProtocol, self_paced_trial
from tests.server.apps import recorded, subject
from tests.walks import walk_frames


@functools.cache
def _speed_changes() -> list[SensorFrame]:
    """Cohort subject 1's self-paced walk: 30 strides with a change of speed every 4 to 8."""
    return frames_from_table(self_paced_trial(make_subjects(CohortSpec())[1], 0, IntentProtocol()).sensors)


def _intent(runtime: object) -> IntentEstimator:
    stack = runtime.estimator.stack  # type: ignore[attr-defined]
    est = stack.estimators[list(stack.names).index("intent")]
    assert isinstance(est, IntentEstimator)
    return est


def test_fit_on_a_walk_run_it_next_session_record_it_and_go_back_to_the_default(client: TestClient) -> None:
    sid = subject(client)
    default = client.get(f"/api/subjects/{sid}/intent-model").json()
    assert default["variant"] == "uninjured" and default["kappa"] == list(COHORT.kappa) and default["steps"] == 0
    tid, _ = recorded(client, sid, _speed_changes())

    r = client.put(f"/api/subjects/{sid}/intent-model", json={"trial_id": tid, "note": "calibration walk"})
    assert r.status_code == 200, r.text
    fitted = r.json()
    assert fitted["source_trial_id"] == tid and fitted["source"].startswith(f"fitted on trial {tid}")
    assert fitted["steps"] >= 40 and 0.0 < fitted["step_rmse_m"] < 0.05 and fitted["alpha"] is None
    # the walker's own model is near the cohort's (a cohort subject walking as the cohort does)
    assert np.allclose(fitted["kappa"], COHORT.kappa, atol=0.15), fitted["kappa"]
    assert client.get(f"/api/subjects/{sid}/intent-model").json()["kappa"] == fitted["kappa"]
    entries = client.get("/api/audit?action=intent_model.set").json()
    assert entries and entries[0]["target"] == f"subject {sid}"
    assert json.loads(entries[0]["after"])["kappa"] == fitted["kappa"]

    # the next session runs it, and its recording says so (a re-run builds the same filter)
    tid2, runtime = recorded(client, sid, walk_frames(6))
    assert _intent(runtime).filter.config.kappa == tuple(fitted["kappa"])
    path = client.app.state.ctx.settings.data_dir / client.get(f"/api/trials/{tid2}").json()["path"]  # type: ignore[attr-defined]
    config = from_metadata(metadata_of(path, METADATA_NAME)[INTENT_MODEL_KEY])
    assert config is not None and config.kappa == tuple(fitted["kappa"])

    # the iSCI variant fitted on a walk with the hip motor's current: eq. 14's alpha too, seed 001's iSCI noise
    r = client.put(f"/api/subjects/{sid}/intent-model", json={"trial_id": tid, "variant": "isci"})
    assert r.status_code == 200, r.text
    isci = r.json()
    assert isci["variant"] == "isci" and len(isci["alpha"]) == 2 and all(np.isfinite(isci["alpha"]))
    _, runtime = recorded(client, sid, walk_frames(3))
    config = _intent(runtime).filter.config
    assert config.alpha == tuple(isci["alpha"]) and config.q_t == ISCI.q_t and config.r_t == ISCI.r_t

    # the iSCI variant's default: seed 001's iSCI tuning
    r = client.put(f"/api/subjects/{sid}/intent-model", json={"variant": "isci"})
    assert r.status_code == 200, r.text
    assert r.json()["kappa"] == list(ISCI.kappa) and r.json()["alpha"] == list(ISCI.alpha or ())
    _, runtime = recorded(client, sid, walk_frames(3))
    assert _intent(runtime).filter.config == ISCI

    # back to the default; once more is a 404
    r = client.delete(f"/api/subjects/{sid}/intent-model")
    assert r.status_code == 200 and r.json()["kappa"] == list(COHORT.kappa)
    assert client.delete(f"/api/subjects/{sid}/intent-model").status_code == 404
    _, runtime = recorded(client, sid, walk_frames(3))
    assert _intent(runtime).filter.config == COHORT


def test_a_walk_that_cannot_fit_is_refused_saying_why_and_nothing_changes(client: TestClient) -> None:
    sid, other = subject(client), subject(client, "OTHER")
    steady, _ = recorded(client, sid, walk_frames(4))  # 8 steps: too few
    r = client.put(f"/api/subjects/{sid}/intent-model", json={"trial_id": steady})
    assert r.status_code == 422 and "usable steps" in r.json()["detail"] and "at least 20" in r.json()["detail"]
    no_current = [f.model_copy(update={"motor_current_A": None}) for f in _speed_changes()]
    walk, _ = recorded(client, sid, no_current)
    r = client.put(f"/api/subjects/{sid}/intent-model", json={"trial_id": walk, "variant": "isci"})
    assert r.status_code == 422 and "needs motor_current_A" in r.json()["detail"]
    r = client.put(f"/api/subjects/{other}/intent-model", json={"trial_id": walk})
    assert r.status_code == 422 and "is not of subject" in r.json()["detail"]
    for body in ({"variant": "paraplegic"}, {"trial_id": 0}, {"kappa": [1, 2, 3]}):
        assert client.put(f"/api/subjects/{sid}/intent-model", json=body).status_code == 422, body
    assert client.put("/api/subjects/9999/intent-model", json={}).status_code == 404
    assert client.get(f"/api/subjects/{sid}/intent-model").json()["steps"] == 0  # still the default
