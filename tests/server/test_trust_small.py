"""Issue #23, 9 ("smaller"), against the real app, SQLite and MCAP: notes taken live listed in review, a file
uploaded twice refused unless a copy is asked for, the login's tries left and its lockout said, and a trial
still recording shown with its length so far."""

from __future__ import annotations

from fastapi.testclient import TestClient

from gaitscope.server.routes.uploads import DUPLICATE_HEADER
from tests.server.apps import session, subject, wait_samples
from tests.uploads import send
from tests.walks import replay_csv


def test_notes_taken_live_are_listed_with_the_review_notes(client: TestClient) -> None:
    s = session(client)
    wait_samples(client, s["id"], 0.5)
    r = client.post(f"/api/sessions/{s['id']}/annotations", json={"text": "subject stumbles", "actor": "dr-k"})
    assert r.status_code == 201, r.text
    live_t = r.json()["t"]
    wait_samples(client, s["id"], 1.5)
    client.post(f"/api/sessions/{s['id']}/stop")
    tid = client.get(f"/api/trials?session_id={s['id']}").json()[0]["id"]
    url = f"/api/trials/{tid}/annotations"
    r = client.post(url, json={"t": 0.2, "text": "warm-up"})
    assert r.status_code == 201, r.text
    notes = client.get(url).json()
    assert [(n["text"], n["source"], n["t"]) for n in notes] == [
        ("warm-up", "review", 0.2),
        ("subject stumbles", "live", live_t),
    ]
    assert notes[1]["actor"] == "local" and notes[1]["t_end"] is None  # accounts off: the local user
    assert 0.4 < live_t < 1.6


def test_a_file_uploaded_twice_is_refused_naming_its_trial_unless_a_copy_is_asked_for(client: TestClient) -> None:
    sid = subject(client)
    data = replay_csv()
    first = send(client, "walk.csv", data, sid)
    assert first.status_code == 201, first.text
    trial = first.json()
    again = send(client, "walk again.csv", data, subject(client, "P02"))  # another name, another subject: same bytes
    assert again.status_code == 409
    assert again.headers[DUPLICATE_HEADER] == str(trial["id"])
    detail = again.json()["detail"]
    assert detail.startswith(f"walk again.csv was uploaded already, as trial {trial['id']} (walk.csv, ")
    assert "nothing was stored" in detail and "keep_copy" in detail
    assert [t["id"] for t in client.get("/api/trials").json()] == [trial["id"]]
    assert not list((client.app.state.ctx.settings.data_dir / "uploads").iterdir())  # type: ignore[attr-defined]
    # asked for: a second copy is stored as a trial of its own; another file is not a duplicate
    r = client.post("/api/uploads", json={"filename": "walk.csv", "size": len(data), "subject_id": sid})
    up = r.json()
    for off in range(0, len(data), up["chunk_size"]):
        client.put(f"/api/uploads/{up['id']}?offset={off}", content=data[off : off + up["chunk_size"]])
    copy = client.post(f"/api/uploads/{up['id']}/finish?keep_copy=true")
    assert copy.status_code == 201, copy.text
    other = send(client, "walk.csv", data.replace(b"\n", b"\r\n"), sid)
    assert other.status_code == 201, other.text
    assert len({trial["id"], copy.json()["id"], other.json()["id"]}) == 3
    sessions = {x["id"]: x for x in client.get("/api/sessions").json()}
    digests = [sessions[t["session_id"]]["source"]["sha256"] for t in (trial, copy.json(), other.json())]
    assert digests[0] == digests[1] != digests[2] and len(digests[0]) == 64
