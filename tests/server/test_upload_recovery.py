"""Upload refusals in the user's terms and the recovery of a recording that was never finished, through the
real app, SQLite and a real recorded session."""

from __future__ import annotations

from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from gaitscope.server.routes.uploads import RECOVERABLE, RECOVERABLE_HEADER
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.formats.mcap_io import check_mcap
from tests.uploads import send
from tests.waiting import wait_until

SHORT = {"kind": "simulated", "protocol": [{"speed_m_s": 1.0, "incline_deg": 0.0, "strides": 200}], "rate_hz": 200}


@pytest.fixture
def recorded(client: TestClient) -> tuple[int, dict, bytes]:
    """A subject and a 2 s recorded trial of theirs, with its MCAP bytes."""
    sid = client.post("/api/subjects", json={"code": "UPL01", "leg_length_m": 0.9, "mass_kg": 70.0}).json()["id"]
    s = client.post("/api/sessions", json={"subject_id": sid, "source": SHORT}).json()
    runtime = client.app.state.ctx.manager.get(s["id"])  # type: ignore[attr-defined]
    wait_until(lambda: runtime.samples >= 400, 20.0, "2 s of samples")
    client.post(f"/api/sessions/{s['id']}/stop")
    trial = client.get(f"/api/trials?session_id={s['id']}").json()[0]
    return sid, trial, client.get(f"/api/trials/{trial['id']}/download").content


def test_a_bad_value_is_named_by_row_and_column(client: TestClient) -> None:
    sid = client.post("/api/subjects", json={"code": "UPL02", "leg_length_m": 0.9, "mass_kg": 70.0}).json()["id"]
    r = send(client, "walk.csv", b"time_s,foot_angle_deg\n0.00,10\n0.01,11\n0.02,eleven\n", sid)
    assert r.status_code == 422
    assert r.json()["detail"] == "file walk.csv, column 'foot_angle_deg', row 4: not a number: 'eleven'"
    assert RECOVERABLE_HEADER not in r.headers
    r = send(client, "walk.txt.csv", b"\x89MCAP0\r\n" + bytes(40), sid)
    assert (
        r.status_code == 422 and r.json()["detail"] == "file walk.txt.csv: not a CSV file: the content is an MCAP file"
    )


def test_an_unfinished_recording_is_refused_as_recoverable_then_recovered(
    client: TestClient, tmp_path: Path, recorded: tuple[int, dict, bytes]
) -> None:
    sid, trial, whole = recorded
    cut = whole[: int(len(whole) * 0.7)]
    (tmp_path / "cut.mcap").write_bytes(cut)
    with pytest.raises(DataFormatError, match=RECOVERABLE):  # what the server recognises, from mcap_io
        check_mcap(tmp_path / "cut.mcap")
    r = send(client, "session_cut.mcap", cut, sid)
    assert r.status_code == 422 and r.headers[RECOVERABLE_HEADER] == "1"
    detail = r.json()["detail"]
    assert detail.startswith("file session_cut.mcap: the MCAP file is incomplete (its recording was never finished")
    assert "can recover" in detail and str(tmp_path) not in detail and "uploads" not in detail
    assert client.get("/api/trials").json() == [trial]  # nothing stored
    assert not list((tmp_path / "data" / "uploads").glob("*"))  # and nothing left behind

    r = send(client, "session_cut.mcap", cut, sid, recover=True)
    assert r.status_code == 201, r.text
    new = r.json()
    assert new["status"] == "uploaded" and new["name"] == "session_cut.mcap"
    assert 0.3 * trial["samples"] < new["samples"] < trial["samples"]
    series = client.get(f"/api/trials/{new['id']}/series?max_points=20000").json()
    assert len(series["t"]) == new["samples"]


def test_recover_on_a_finished_recording_imports_it_as_it_is(
    client: TestClient, recorded: tuple[int, dict, bytes]
) -> None:
    sid, trial, whole = recorded
    r = send(client, "whole.mcap", whole, sid, recover=True)
    assert r.status_code == 201 and r.json()["samples"] == trial["samples"]


def test_nothing_to_recover_says_what_is_missing(
    client: TestClient, tmp_path: Path, recorded: tuple[int, dict, bytes]
) -> None:
    sid, trial, _ = recorded
    r = send(client, "junk.mcap", b"\x89MCAP0\r\n" + bytes(64), sid, recover=True)
    assert r.status_code == 422
    assert r.json()["detail"] == "file junk.mcap: no /sensor channel (gaitscope needs the raw sensor frames)"
    assert client.get("/api/trials").json() == [trial]
