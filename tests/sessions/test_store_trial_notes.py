"""A trial's notes in the store (``Store.trial_notes``): those added in review and those taken live while it
recorded (issue #23, 9), on a real database."""

from __future__ import annotations

import pytest

from gaitscope.sessions import schema
from gaitscope.sessions.store import NotFound, Store


@pytest.fixture
def store(database_url: str) -> Store:
    s = Store(database_url)
    subject = s.create_subject(schema.SubjectCreate(code="N01", leg_length_m=0.9, mass_kg=70.0))
    session = s.create_session(schema.SessionCreate(subject_id=subject.id, start=False))
    s.create_trial(session.id, "walk", "recordings/a.mcap")
    s.create_trial(session.id, "run", "recordings/b.mcap")
    return s


def test_live_notes_are_listed_with_the_review_notes_by_time(store: Store) -> None:
    store.add_event(1, t=0.5, kind="annotation", text="before any trial", actor="dr-k")  # no trial: not listed
    stumble = store.add_event(1, t=3.0, kind="annotation", text="subject stumbles", actor="dr-k", trial_id=1)
    store.add_event(1, t=3.5, kind="system", text="primary switched", trial_id=1)  # not a note
    store.add_event(1, t=4.0, kind="annotation", text="other trial", actor="dr-k", trial_id=2)
    review = store.add_review_annotation(1, schema.ReviewAnnotationCreate(t=1.0, t_end=2.0, text="span", actor="ana"))
    late = store.add_review_annotation(1, schema.ReviewAnnotationCreate(t=3.0, text="same time", actor="ana"))
    notes = store.trial_notes(1)
    assert [(n.text, n.source, n.actor, n.t) for n in notes] == [
        ("span", "review", "ana", 1.0),
        ("subject stumbles", "live", "dr-k", 3.0),  # at the same time, the live note first
        ("same time", "review", "ana", 3.0),
    ]
    live = notes[1]
    assert (live.id, live.trial_id, live.t_end, live.created_utc) == (stumble.id, 1, None, stumble.wall_utc)
    assert notes[0] == review and notes[2] == late
    assert store.list_review_annotations(1) == [review, late]  # the review's own notes alone, as before
    assert [n.text for n in store.trial_notes(2)] == ["other trial"]
    with pytest.raises(NotFound):
        store.trial_notes(99)
