"""Review of a trial recorded by a real session: A/B comparison of named re-runs (``/compare``), review notes
(``/annotations``) and a trial still recording, against the real app, SQLite and MCAP."""

from __future__ import annotations

import math

import pytest
from fastapi.testclient import TestClient

from tests.server.apps import SHORT, session, wait_samples


@pytest.fixture
def trial(client: TestClient) -> tuple[int, int]:
    """(session id, trial id) of a finished 3-second recording of a simulated walk, with a gain change."""
    s = session(client)
    wait_samples(client, s["id"], 1.0)
    r = client.patch(f"/api/sessions/{s['id']}/settings", json={"torque_gain": 1.3, "actor": "dr-k", "confirm": True})
    assert r.status_code == 200, r.text
    wait_samples(client, s["id"], 3.0)
    client.post(f"/api/sessions/{s['id']}/stop")
    trials = client.get(f"/api/trials?session_id={s['id']}").json()
    return s["id"], trials[0]["id"]


def test_compare_two_named_runs_against_the_truth(client: TestClient, trial: tuple[int, int]) -> None:
    _, tid = trial
    body = {"runs": [{"name": "as recorded"}, {"name": "gain 0.5", "settings": {"torque_gain": 0.5}}]}
    r = client.post(f"/api/trials/{tid}/compare?max_points=400", json=body)
    assert r.status_code == 200, r.text
    c = r.json()
    assert [run["name"] for run in c["runs"]] == ["as recorded", "gain 0.5"]
    assert c["ground_truth"] == "the simulated walk (cohort subject 0, seed 7)"
    assert 10 <= len(c["t"]) <= 400 and c["t"] == sorted(c["t"])
    assert len(c["stride_pct"]) == 101 and c["stride_pct"][-1] == 100.0
    a, b = c["runs"]
    for run in (a, b):
        assert len(run["torque_Nm"]) == len(run["phase_pct"]) == len(run["torque_diff_Nm"]) == len(c["t"])
        f = run["figures"]
        assert f["strides"] >= 1
        assert 0.5 < f["mean_phase_rate_1_s"] < 1.5  # about a stride a second at 1.2 m/s
        assert 0.8 < f["mean_stride_length_m"] < 2.0
        assert 0 < f["phase_rmse_pct"] < 5  # against the simulated truth: a wrong alignment gives ~29
        assert f["stride_length_rmse_m"] is not None and f["incline_rmse_deg"] is not None
    # the reference's difference from itself is zero; the estimator is the same, so phase agrees too
    assert all(d == 0 for d in a["torque_diff_Nm"] if d is not None)
    assert all(abs(d) < 1e-9 for d in b["phase_diff_pct"] if d is not None)
    # half the gain: less peak torque than the recording (1.0, then 1.3; the soft start caps both alike)
    assert 0.3 * a["figures"]["peak_torque_Nm"] < b["figures"]["peak_torque_Nm"] < 0.8 * a["figures"]["peak_torque_Nm"]
    assert min(d for d in b["torque_diff_Nm"] if d is not None) < -1.0
    # the as-recorded run reproduces the recording's torque
    rec = client.get(f"/api/trials/{tid}/series?max_points=20000").json()
    by_t = dict(zip(rec["t"], rec["torque_Nm"], strict=True))
    matched = [(by_t[t], x) for t, x in zip(c["t"], a["torque_Nm"], strict=True) if t in by_t]
    assert len(matched) > 10 and all(math.isclose(p, q, abs_tol=1e-9) for p, q in matched)


def test_compare_is_validated(client: TestClient, trial: tuple[int, int]) -> None:
    _, tid = trial
    url = f"/api/trials/{tid}/compare"
    r = client.post(url, json={"runs": [{"name": "A"}]})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "runs"]
    r = client.post(url, json={"runs": [{"name": "A"}, {"name": " a "}]})
    assert r.status_code == 422 and "two re-runs are named 'a'" in r.json()["detail"][0]["msg"]
    r = client.post(url, json={"runs": [{"name": "A"}, {"name": "  "}]})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "runs", 1, "name"]
    r = client.post(url, json={"runs": [{"name": "A"}, {"name": "B", "settings": {"torque_gain": 9}}]})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"][:4] == ["body", "runs", 1, "settings"]
    r = client.post(url, json={"runs": [{"name": str(k)} for k in range(5)]})
    assert r.status_code == 422
    assert client.post("/api/trials/999/compare", json={"runs": [{"name": "A"}, {"name": "B"}]}).status_code == 404


def test_review_notes_saved_listed_and_deleted(client: TestClient, trial: tuple[int, int]) -> None:
    """(Only its author deletes a note: with accounts, ``tests/server/test_auth.py``.)"""
    _, tid = trial
    url = f"/api/trials/{tid}/annotations"
    assert client.get(url).json() == []
    r = client.post(url, json={"t": 2.0, "t_end": 2.5, "text": "toe catch", "actor": "dr-k"})  # actor: ignored
    assert r.status_code == 201, r.text
    span = r.json()
    assert (span["t"], span["t_end"], span["text"], span["actor"], span["trial_id"]) == (
        2.0,
        2.5,
        "toe catch",
        "local",
        tid,
    )
    point = client.post(url, json={"t": 1.0, "text": "  step  "}).json()
    assert (point["t_end"], point["text"], point["actor"]) == (None, "step", "local")
    assert [a["id"] for a in client.get(url).json()] == [point["id"], span["id"]]  # by time
    # validated, each problem named
    r = client.post(url, json={"t": 2.0, "t_end": 1.0, "text": "x"})
    assert r.status_code == 422 and "must end after it starts" in r.json()["detail"][0]["msg"]
    r = client.post(url, json={"t": 1.0, "text": " "})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "text"]
    r = client.post(url, json={"t": 500.0, "text": "late"})
    assert r.status_code == 422 and "outside the trial" in r.json()["detail"]
    assert client.post(url, json={"t": "nan", "text": "x"}).status_code == 422
    assert client.delete(f"{url}/{span['id']}").status_code == 204
    assert client.delete(f"{url}/{span['id']}").status_code == 404
    assert [a["id"] for a in client.get(url).json()] == [point["id"]]
    assert client.get("/api/trials/999/annotations").status_code == 404


def test_a_trial_still_recording_says_so(client: TestClient) -> None:
    s = session(client, SHORT)
    trials = client.get(f"/api/trials?session_id={s['id']}").json()
    assert trials[0]["status"] == "recording"
    r = client.post(f"/api/trials/{trials[0]['id']}/compare", json={"runs": [{"name": "A"}, {"name": "B"}]})
    assert r.status_code == 409 and "still recording" in r.json()["detail"]
