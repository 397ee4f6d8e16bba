"""Uploading a file through the real API, as the browser does (create, chunks, finish)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from fastapi.testclient import TestClient


def upload(client: TestClient, path: Path, subject_id: int) -> dict[str, Any]:
    """Upload ``path`` for ``subject_id`` in the server's chunk size; returns the imported trial."""
    data = path.read_bytes()
    r = client.post("/api/uploads", json={"filename": path.name, "size": len(data), "subject_id": subject_id})
    assert r.status_code == 201, r.text
    up = r.json()
    for off in range(0, len(data), up["chunk_size"]):
        assert client.put(
            f"/api/uploads/{up['id']}?offset={off}", content=data[off : off + up["chunk_size"]]
        ).is_success
    r = client.post(f"/api/uploads/{up['id']}/finish")
    assert r.status_code == 201, r.text
    trial: dict[str, Any] = r.json()
    return trial
