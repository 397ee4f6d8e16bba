"""Issue #23, 9 ("smaller"), against the real app, SQLite and MCAP: notes taken live listed in review, a file
uploaded twice refused unless a copy is asked for, the login's tries left and its lockout said, and a trial
still recording shown with its length so far."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from gaitscope.server.app import create_app
from gaitscope.server.routes.uploads import DUPLICATE_HEADER
from gaitscope.sessions import schema
from gaitscope.sessions.accounts import LoginThrottle
from tests.server.apps import PASSWORD, auth_settings, session, subject, wait_samples
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


class _Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def accounts_app(tmp_path: Path) -> Iterator[tuple[TestClient, _Clock]]:
    """The app with accounts on (lockout after 5, the default) and its throttle on an injected clock."""
    with TestClient(create_app(auth_settings(tmp_path))) as c:
        accounts = c.app.state.ctx.accounts  # type: ignore[attr-defined]
        clock = _Clock()
        accounts.throttle = LoginThrottle(free=5, free_address=20, free_account=20, cap_s=900.0, clock=clock)
        accounts.add_user(schema.UserCreate(name="cleo", role="clinician", password=PASSWORD), by="test")
        yield c, clock


def test_the_login_says_the_tries_left_and_the_lock_the_same_for_a_name_that_does_not_exist(
    accounts_app: tuple[TestClient, _Clock],
) -> None:
    app, clock = accounts_app
    assert isinstance(app.app, FastAPI)

    def tries(name: str) -> list[tuple[int, str, str | None]]:
        guesser = TestClient(app.app, client=(f"10.0.0.{len(name)}", 40000))  # one address per name
        answers = []
        for password in ["wrong 1", "wrong 2", "wrong 3", "wrong 4", "wrong 5", PASSWORD]:
            r = guesser.post("/api/auth/login", json={"name": name, "password": password})
            answers.append((r.status_code, r.json()["detail"], r.headers.get("retry-after")))
        return answers

    known, unknown = tries("cleo"), tries("nobodyy")
    assert known == unknown  # nothing tells a real name from an invented one
    refused = "wrong name or password"
    assert known == [
        (401, refused, None),
        (401, refused, None),
        (401, f"{refused} (2 tries left before logins with this name are locked)", None),
        (401, f"{refused} (1 try left before logins with this name are locked)", None),
        (
            401,
            f"{refused}. Too many failed logins: logins with this name from this computer are locked for 1 s "
            "(each further failure doubles the wait)",
            "1",
        ),
        (401, "locked after too many failed logins: try again in 1 s (this attempt was not checked)", "1"),
    ]
    clock.t = 1.5  # the wait is over: the right password logs in
    r = TestClient(app.app, client=("10.0.0.4", 40000)).post(
        "/api/auth/login", json={"name": "cleo", "password": PASSWORD}
    )
    assert r.status_code == 200, r.text


def test_a_trial_still_recording_is_listed_with_its_length_so_far(client: TestClient) -> None:
    s = session(client)
    wait_samples(client, s["id"], 1.0)
    [trial] = client.get(f"/api/trials?session_id={s['id']}").json()
    assert trial["status"] == "recording" and trial["samples"] >= 100 and trial["duration_s"] >= 0.5
    stored = client.app.state.ctx.store.get_trial(trial["id"])  # type: ignore[attr-defined]
    assert (stored.samples, stored.duration_s) == (0, 0.0)  # the row has them once it stops
    wait_samples(client, s["id"], 2.0)
    again = client.get(f"/api/trials/{trial['id']}").json()
    assert again["samples"] > trial["samples"] and again["duration_s"] > trial["duration_s"]
    client.post(f"/api/sessions/{s['id']}/stop")
    final = client.get(f"/api/trials/{trial['id']}").json()
    assert final["status"] == "finished" and final["samples"] >= again["samples"]
