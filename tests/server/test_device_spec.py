"""The device protocol's machine-readable files (docs/device_protocol) are generated from the schema and up to date."""

from __future__ import annotations

import json
from pathlib import Path

from gaitscope.server.device_spec import MESSAGES, render
from gaitscope.sessions import schema

SPEC = Path(__file__).resolve().parents[2] / "docs" / "device_protocol"


def test_the_files_in_docs_are_what_the_schema_generates() -> None:
    files = render()
    for name, text in files.items():
        assert (SPEC / name).read_text() == text, f"{name} is out of date: run gaitscope device-spec"
    assert sorted(p.name for p in SPEC.iterdir()) == sorted(files)


def test_the_asyncapi_document_names_every_message_and_the_schemas_every_channel() -> None:
    doc = json.loads(render()["asyncapi.json"])
    assert doc["asyncapi"] == "2.6.0" and "/ws/devices/{session_id}" in doc["channels"]
    assert set(doc["components"]["messages"]) == set(MESSAGES)
    frame = json.loads(render()["SensorFrame.schema.json"])
    assert set(schema.CHANNELS) <= set(frame["properties"])
    notice = json.loads(render()["DeviceNotice.schema.json"])
    assert set(notice["properties"]["kind"]["enum"]) == {"invalid", "too_large", "order", "rate", "binary"}
