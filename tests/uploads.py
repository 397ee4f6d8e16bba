"""Uploading a file through the real API, as the browser does (create, chunks, finish)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import httpx2
from fastapi.testclient import TestClient


def send(client: TestClient, name: str, data: bytes, subject_id: int, recover: bool = False) -> httpx2.Response:
    """Upload ``data`` as a file ``name`` for ``subject_id`` in the server's chunk size; the answer to its
    ``finish`` (``recover``: keep what a damaged recording holds up to the damage)."""
    r = client.post("/api/uploads", json={"filename": name, "size": len(data), "subject_id": subject_id})
    assert r.status_code == 201, r.text
    up = r.json()
    for off in range(0, len(data), up["chunk_size"]):
        assert client.put(
            f"/api/uploads/{up['id']}?offset={off}", content=data[off : off + up["chunk_size"]]
        ).is_success
    return client.post(f"/api/uploads/{up['id']}/finish" + ("?recover=true" if recover else ""))


def upload(client: TestClient, path: Path, subject_id: int) -> dict[str, Any]:
    """Upload ``path`` for ``subject_id`` in the server's chunk size; returns the imported trial."""
    r = send(client, path.name, path.read_bytes(), subject_id)
    assert r.status_code == 201, r.text
    trial: dict[str, Any] = r.json()
    return trial
