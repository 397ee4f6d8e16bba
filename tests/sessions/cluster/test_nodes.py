"""Membership of the nodes sharing one database: beats, the takeover of a silent node, fencing, routing.

On the real database (SQLite here, PostgreSQL in the suite's second run), with the nodes' clock injected:
nothing sleeps. ``tests/server/test_cluster.py`` runs the same through real processes and nginx.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from gaitscope.server.app import create_app
from gaitscope.server.settings import Settings
from gaitscope.sessions import schema
from gaitscope.sessions.cluster.membership import beat_once
from gaitscope.sessions.cluster.nodes import Nodes
from gaitscope.sessions.store import Store
from tests.sessions.formats.test_recovery import _unfinished_recording


class Clock:
    """The nodes' UTC wall clock, moved by the test."""

    def __init__(self) -> None:
        self.now = dt.datetime(2026, 11, 27, 8, 0, tzinfo=dt.UTC)

    def __call__(self) -> dt.datetime:
        return self.now

    def advance(self, seconds: float) -> None:
        self.now += dt.timedelta(seconds=seconds)


@pytest.fixture
def store(database_url: str) -> Iterator[Store]:
    s = Store(database_url)
    yield s
    s.close()


def _nodes(store: Store, clock: Clock, *names: str) -> list[Nodes]:
    found = [Nodes(store, name, f"127.0.0.1:{9000 + i}", timeout_s=10.0, clock=clock) for i, name in enumerate(names)]
    for node in found:
        node.register()
    return found


def _session(store: Store, subject_id: int, node: str | None, state: schema.SessionState = "running") -> int:
    session = store.create_session(schema.SessionCreate(subject_id=subject_id, start=False))
    if state != "created":
        store.set_session_state(session.id, state, node)
    return session.id


def test_a_silent_node_is_declared_gone_once_and_a_fenced_node_learns_it(store: Store) -> None:
    clock = Clock()
    a, b, c = _nodes(store, clock, "a", "b", "c")
    assert [(n.name, n.live) for n in a.nodes()] == [("a", True), ("b", True), ("c", True)]
    clock.advance(9.0)
    assert a.beat() and c.beat()
    assert a.claim_gone() == []  # b's beat is 9 s old: within the timeout
    clock.advance(2.0)
    assert a.claim_gone() == ["b"]
    assert c.claim_gone() == []  # already claimed: one survivor recovers it, never two
    assert {n.name: (n.state, n.live) for n in c.nodes()}["b"] == ("gone", False)
    assert not b.beat() and b.gone_by() == "a"  # b stalled past the timeout: it is fenced
    b.register()
    assert b.beat() and {n.name: n.live for n in a.nodes()}["b"]


def test_a_node_timeout_shorter_than_two_beats_is_refused(store: Store) -> None:
    with pytest.raises(ValueError, match="must exceed two beats"):
        Nodes(store, "a", "127.0.0.1:1", timeout_s=1.5)


def test_requests_go_to_the_node_that_runs_the_session_and_new_ones_to_the_least_loaded(store: Store) -> None:
    clock = Clock()
    a, b, _ = _nodes(store, clock, "a", "b", "c")
    subject = store.create_subject(schema.SubjectCreate(code="R1", leg_length_m=0.9, mass_kg=70.0)).id
    on_b = _session(store, subject, "b")
    on_a = [_session(store, subject, "a") for _ in range(2)]
    created = _session(store, subject, None, "created")
    stopped_on_b = _session(store, subject, "b", "stopped")
    for uri in (f"/ws/devices/{on_b}?token=x", f"/ws/sessions/{on_b}", f"/api/sessions/{on_b}/settings"):
        assert a.route("GET", uri).name == "b", uri
    assert a.route("POST", f"/api/sessions/{on_a[0]}/stop").address == "127.0.0.1:9000"
    # new sessions, a created one's start and everything else: the node with fewest sessions
    for method, uri in (("POST", "/api/sessions"), ("POST", f"/api/sessions/{created}/start"), ("GET", "/api/x")):
        assert b.route(method, uri).name == "c", uri
    # a session that runs nowhere: one node chosen by its id, whoever asks, whatever the path
    for sid in (stopped_on_b, created, 99999):
        chosen = {n.route("GET", f"/api/sessions/{sid}{p}").name for n in (a, b) for p in ("", "/summary/progress")}
        assert len(chosen) == 1, (sid, chosen)
    assert len({a.route("GET", f"/api/sessions/{sid}").name for sid in range(100, 160)}) == 3  # spread over all
    _session(store, subject, "c")
    _session(store, subject, "c")
    assert a.route("POST", "/api/sessions").name == "b"  # a 2, b 1, c 2
    clock.advance(11.0)
    a.beat()
    assert a.claim_gone() == ["b", "c"]
    assert a.route("GET", f"/ws/devices/{on_b}").name == "a"  # its node is gone: a survivor answers for it


def _app(data: Path, database_url: str, node: str) -> TestClient:
    """The app as node ``node``, on the test's database."""
    settings = Settings(
        data_dir=data, database_url=database_url, demo=False, leg_view=False, allowed_hosts=["testserver"], node=node
    )
    return TestClient(create_app(settings))


def test_a_survivor_stops_a_gone_nodes_sessions_and_recovers_its_recordings(
    tmp_path: Path, store: Store, database_url: str
) -> None:
    data = tmp_path / "data"
    subject = store.create_subject(schema.SubjectCreate(code="T1", leg_length_m=0.9, mass_kg=70.0)).id
    gone, mine, elsewhere = (_session(store, subject, node) for node in ("b", "a", "c"))
    trial = store.create_trial(gone, "walk", "recordings/walk.mcap")
    store.create_trial(elsewhere, "theirs", "recordings/theirs.mcap")
    _unfinished_recording(data / "recordings/walk.mcap", samples=700)
    with _app(data, database_url, "a") as client:
        manager = client.app.state.ctx.manager  # type: ignore[attr-defined]
        assert [t.id for t in manager.recover_after_crash("b")] == [trial.id]
    states = {s.id: s.state for s in store.list_sessions()}
    assert states == {gone: "stopped", mine: "stopped", elsewhere: "running"}  # a's own: by its own start-up
    walk = store.get_trial(trial.id)
    assert walk.status == "recovered" and walk.samples > 0
    texts = [e.text for e in store.list_events(gone)]
    assert texts[-1] == "server process b stopped answering: session stopped", texts
    assert [t.status for t in store.list_trials(elsewhere)] == ["recording"]  # c's: not a's to recover


def test_a_fenced_node_stops_what_it_still_runs(tmp_path: Path, database_url: str) -> None:
    clock = Clock()
    with _app(tmp_path / "data", database_url, "b") as client:
        ctx = client.app.state.ctx  # type: ignore[attr-defined]
        subject = client.post("/api/subjects", json={"code": "F1", "leg_length_m": 0.9, "mass_kg": 70}).json()
        sid = client.post("/api/sessions", json={"subject_id": subject["id"]}).json()["id"]
        assert client.get(f"/api/sessions/{sid}").json()["state"] == "running"
        a, b = (Nodes(ctx.store, name, "127.0.0.1:1", clock=clock) for name in ("a", "b"))
        a.register()
        b.register()
        clock.advance(11.0)
        a.beat()
        assert a.claim_gone() == ["b"]
        assert client.portal.call(beat_once, b, ctx.manager, ctx.writer) == []  # type: ignore[union-attr]
        assert ctx.manager.get(sid) is None
        assert client.get(f"/api/sessions/{sid}").json()["state"] == "stopped"
        assert b.beat()  # registered again
