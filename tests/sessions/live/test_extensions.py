"""Session extensions (:mod:`gaitscope.sessions.live.extensions`): the runtime calls only the hooks an extension
overrides, in the extensions' order, and builds the extensions its stack needs."""

from __future__ import annotations

from fastapi.testclient import TestClient

from gaitscope.sessions import schema
from gaitscope.sessions.live.extensions import Outputs, SessionExtension, hooked
from gaitscope.sessions.live.runtime import SessionRuntime
from gaitscope.sessions.live.sources import LiveDevice
from gaitscope.sessions.store_writer import StoreWriter


class _Counts(SessionExtension):
    def __init__(self, name: str, calls: list[str]):
        self.name, self.calls = name, calls

    def on_sample(self, state: schema.GaitState, outputs: Outputs) -> None:
        self.calls.append(self.name)


class _Ticks(SessionExtension):
    def on_tick(self) -> None:
        raise AssertionError("not a sample hook")


def test_only_the_hooks_an_extension_overrides_are_called_in_order() -> None:
    calls: list[str] = []
    extensions = [_Counts("a", calls), _Ticks(), _Counts("b", calls)]
    on_sample = hooked(extensions, "on_sample")
    assert len(on_sample) == 2 and len(hooked(extensions, "on_tick")) == 1 and hooked(extensions, "stop") == []
    for hook in on_sample:
        hook(schema.GaitState.model_construct(seq=0, t=0.0), [])
    assert calls == ["a", "b"]
    assert SessionExtension().health() == {}


def _runtime(client: TestClient, writer: StoreWriter, estimators: list[str]) -> SessionRuntime:
    ctx = client.app.state.ctx  # type: ignore[attr-defined]
    r = client.post("/api/subjects", json={"code": f"EX{len(estimators)}", "leg_length_m": 0.9, "mass_kg": 70})
    body = {"subject_id": r.json()["id"], "source": {"kind": "device"}, "settings": {"estimators": estimators},
            "start": False}  # fmt: skip
    session = ctx.store.get_session(client.post("/api/sessions", json=body).json()["id"])
    model, _ = ctx.models.get(session.settings.model)
    subject = ctx.store.get_subject(session.subject_id)
    return SessionRuntime(session, subject, model, LiveDevice(), ctx.store, ctx.settings.data_dir, writer=writer)


def test_a_runtime_runs_the_extensions_its_stack_needs_in_a_fixed_order(client: TestClient) -> None:
    writer = StoreWriter()
    try:
        plain = _runtime(client, writer, ["phase_ekf"])
        with_intent = _runtime(client, writer, ["phase_ekf", "intent"])
    finally:
        writer.close()
    common = ["DiskWatch", "EstimatorNotes", "ImuEvents", "ImuCalibrating", "Personalization"]
    assert [type(e).__name__ for e in plain.extensions] == common
    assert [type(e).__name__ for e in with_intent.extensions] == [*common[:2], "IntentEvents", *common[2:]]
    assert plain.gp_learning is None and plain.learning is None
    assert plain.health().disk == "ok" and plain.health().imu is None  # the extensions' parts of data health
