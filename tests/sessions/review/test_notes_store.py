"""Review notes in the store (``Store.add_review_annotation`` and friends) on a real database (SQLite, or
PostgreSQL when the suite runs against one)."""

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
