"""Review notes in the store (``Store.add_review_annotation`` and friends; ``Store.trial_notes``, with the notes
taken live) on a real database (SQLite, or PostgreSQL when the suite runs against one)."""

from __future__ import annotations

import pytest

from gaitscope.sessions import schema
from gaitscope.sessions.store import NotAllowed, NotFound, Store


@pytest.fixture
def store(database_url: str) -> Store:
    s = Store(database_url)
    subject = s.create_subject(schema.SubjectCreate(code="N01", leg_length_m=0.9, mass_kg=70.0))
    session = s.create_session(schema.SessionCreate(subject_id=subject.id, start=False))
    s.create_trial(session.id, "walk", "recordings/a.mcap")
    s.create_trial(session.id, "run", "recordings/b.mcap")
    return s


def test_notes_round_trip_by_time_per_trial(store: Store) -> None:
    late = store.add_review_annotation(1, schema.ReviewAnnotationCreate(t=5.0, text="late", actor="dr-k"))
    span = store.add_review_annotation(1, schema.ReviewAnnotationCreate(t=1.0, t_end=2.5, text="span"))
    other = store.add_review_annotation(2, schema.ReviewAnnotationCreate(t=0.5, text="other trial"))
    assert (late.id, late.trial_id, late.t, late.t_end, late.actor) == (1, 1, 5.0, None, "dr-k")
    assert (span.t, span.t_end, span.actor) == (1.0, 2.5, "local") and span.created_utc
    assert [n.text for n in store.list_review_annotations(1)] == ["span", "late"]
    assert store.list_review_annotations(2) == [other]


def test_only_the_author_deletes_a_note_of_that_trial(store: Store) -> None:
    note = store.add_review_annotation(1, schema.ReviewAnnotationCreate(t=1.0, text="x", actor="dr-k"))
    with pytest.raises(NotAllowed, match="written by dr-k"):
        store.delete_review_annotation(1, note.id, "clinician")
    with pytest.raises(NotFound, match="trial 2 has no note 1"):
        store.delete_review_annotation(2, note.id, "dr-k")
    store.delete_review_annotation(1, note.id, "dr-k")
    assert store.list_review_annotations(1) == []
    with pytest.raises(NotFound):
        store.delete_review_annotation(1, note.id, "dr-k")
    with pytest.raises(NotFound, match="trial 9 does not exist"):
        store.add_review_annotation(9, schema.ReviewAnnotationCreate(t=1.0, text="x"))


def test_a_note_is_validated() -> None:
    with pytest.raises(ValueError, match="must end after it starts"):
        schema.ReviewAnnotationCreate(t=2.0, t_end=2.0, text="x")
    with pytest.raises(ValueError, match="must not be blank"):
        schema.ReviewAnnotationCreate(t=2.0, text="   ")
    with pytest.raises(ValueError):
        schema.ReviewAnnotationCreate(t=float("inf"), text="x")
    assert schema.ReviewAnnotationCreate(t=0.0, text="  trimmed ").text == "trimmed"


# --- a trial's notes: those added in review and those taken live while it recorded (issue #23, 9) ---------


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
