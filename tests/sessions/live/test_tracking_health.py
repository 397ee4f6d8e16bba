"""Data health says how the primary tracks the gait: walking, standing still, lost (issue #10)."""

from __future__ import annotations

import time

from fastapi.testclient import TestClient

from gaitscope.sessions import schema
from gaitscope.sessions.live.runtime import SessionRuntime
from gaitscope.sessions.live.sources import LiveDevice, frames_from_table
from gaitscope.sessions.synth.cohort import CohortSpec, make_subjects
from gaitscope.sessions.synth.real_walks import RealWalkSpec, real_walk


def test_health_reports_walking_and_standing_still(client: TestClient) -> None:
    ctx = client.app.state.ctx  # type: ignore[attr-defined]
    r = client.post("/api/subjects", json={"code": "T01", "leg_length_m": 0.9, "mass_kg": 75})
    body = {"subject_id": r.json()["id"], "source": {"kind": "device"}, "start": False}
    session = ctx.store.get_session(client.post("/api/sessions", json=body).json()["id"])
    model, _ = ctx.models.get(session.settings.model)
    runtime = SessionRuntime(session, ctx.store.get_subject(session.subject_id), model, LiveDevice(), ctx.store,
                             ctx.settings.data_dir)  # fmt: skip
    walk = real_walk(make_subjects(CohortSpec())[0], RealWalkSpec(bouts=1, dropouts_per_min=0.0))
    seen = set()
    for frame, condition in zip(
        frames_from_table(walk[["time_s", *schema.REPLAY_SIGNALS]]), walk["condition"], strict=True
    ):
        runtime.process(frame, time.time_ns())
        h = runtime.health()
        seen.add((condition, h.tracking))
    assert ("steady", "walking") in seen
    assert ("standing", "standing") in seen
    assert all(tracking in ("walking", "standing", "lost") for _, tracking in seen)
