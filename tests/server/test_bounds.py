"""Out-of-range numbers are refused with a reason, never a 500: every integer in a path, a query or a body is
bounded to what the database holds (a signed 64-bit integer, ``schema.INT64_MAX``), every float is finite.

Two checks: the declared bounds of every route's parameters and body fields (the app's routes and the pydantic
models they take, walked), and the real app answering every route with an id, each id in turn set to
2**63, 2**64, -1, 0, "abc" and "1e308", plus the cases found by hand (issue #21).
"""

from __future__ import annotations

import json
import re
import types
import typing
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import annotated_types as at
import pytest
from fastapi.routing import APIRoute, APIWebSocketRoute
from fastapi.testclient import TestClient
from pydantic import BaseModel
from pydantic.fields import FieldInfo
from starlette.websockets import WebSocketDisconnect

from gaitscope.server.app import create_app
from gaitscope.server.settings import Settings
from gaitscope.sessions import schema
from tests.server.apps import app_routes

BAD_IDS = [str(2**63), str(2**64), "-1", "0", "abc", "1e308", "nan"]


def _leaves(tp: Any, metadata: tuple[Any, ...] = ()) -> Iterator[tuple[Any, tuple[Any, ...]]]:
    """The scalar types (with their Annotated constraints) and models a field's type is made of."""
    origin = typing.get_origin(tp)
    if origin is typing.Annotated:
        inner, *more = typing.get_args(tp)
        extra: list[Any] = []
        for m in more:
            extra.extend(m.metadata if isinstance(m, FieldInfo) else [m])
        yield from _leaves(inner, metadata + tuple(extra))
    elif origin is typing.Literal:
        return
    elif origin in (typing.Union, types.UnionType, list, tuple, dict, set, frozenset):
        for arg in typing.get_args(tp):
            if arg is not Ellipsis:
                yield from _leaves(arg, metadata)
    else:
        yield tp, metadata


def _unbounded(kind: type, metadata: tuple[Any, ...]) -> bool:
    lo = next((m for m in metadata if isinstance(m, (at.Ge, at.Gt))), None)
    hi = next((getattr(m, "le", getattr(m, "lt", None)) for m in metadata if isinstance(m, (at.Le, at.Lt))), None)
    if kind is int:
        return lo is None or hi is None or hi > schema.INT64_MAX
    finite = any(getattr(m, "allow_inf_nan", None) is False for m in metadata)
    return not (finite or (lo is not None and hi is not None))  # bounds on both sides refuse NaN and inf too


def _field_problems(model: type[BaseModel], seen: set[type[BaseModel]]) -> Iterator[str]:
    if model in seen:
        return
    seen.add(model)
    for name, info in model.model_fields.items():
        for leaf, metadata in _leaves(info.annotation, tuple(info.metadata)):
            if isinstance(leaf, type) and issubclass(leaf, BaseModel):
                yield from _field_problems(leaf, seen)
            elif leaf in (int, float) and _unbounded(leaf, metadata):
                yield f"{model.__name__}.{name}: {leaf.__name__} without bounds"


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    settings = Settings(
        data_dir=tmp_path_factory.mktemp("bounds") / "data", demo=False, leg_view=False, disk_warn_mb=1,
        disk_stop_mb=1, upload_min_free_mb=1, allowed_hosts=["testserver"],
    )  # fmt: skip
    with TestClient(create_app(settings), raise_server_exceptions=False) as c:
        r = c.post("/api/subjects", json={"code": "B01", "leg_length_m": 0.9, "mass_kg": 70.0})
        assert r.status_code == 201, r.text
        yield c


def test_every_number_a_route_takes_is_bounded(client: TestClient) -> None:
    problems: list[str] = []
    seen: set[type[BaseModel]] = set()
    for route in app_routes(client.app.routes):  # type: ignore[attr-defined]
        if not isinstance(route, (APIRoute, APIWebSocketRoute)):
            continue
        d = route.dependant
        for param in d.path_params + d.query_params + d.body_params:
            info = param.field_info
            for leaf, metadata in _leaves(info.annotation, tuple(info.metadata)):
                if isinstance(leaf, type) and issubclass(leaf, BaseModel):
                    problems.extend(_field_problems(leaf, seen))
                elif leaf in (int, float) and _unbounded(leaf, metadata):
                    problems.append(f"{route.path} {param.name}: {leaf.__name__} without bounds")
    assert sorted(set(problems)) == []
    assert schema.ViewerShow in seen and schema.UploadCreate in seen and schema.SessionCreate in seen


def _id_routes(client: TestClient) -> list[tuple[str, str, list[str]]]:
    out = []
    for route in app_routes(client.app.routes):  # type: ignore[attr-defined]
        if isinstance(route, APIRoute) and (names := re.findall(r"\{(\w+)\}", route.path)):
            out.extend((method, route.path, names) for method in sorted(route.methods))
    return out


def test_every_route_with_an_id_refuses_out_of_range_ids_with_a_4xx(client: TestClient) -> None:
    checked = 0
    for method, path, names in _id_routes(client):
        for name in names:
            for bad in BAD_IDS:
                url = re.sub(r"\{(\w+)\}", lambda m, n=name, b=bad: b if m[1] == n else "1", path)  # type: ignore[misc]
                body = {} if method in ("POST", "PUT", "PATCH") else None
                r = client.request(method, url, json=body, params={"offset": 0} if method == "PUT" else None)
                assert 400 <= r.status_code < 500, (method, url, r.status_code, r.text)
                assert r.json()["detail"], (method, url)
                checked += 1
    assert checked >= 40 * len(BAD_IDS)


@pytest.mark.parametrize(
    ("method", "url", "body", "where"),
    [
        ("PUT", f"/api/subjects/{2**63}/assistance-limits", {}, "subject_id"),
        ("POST", f"/api/subjects/{2**63}/fingerprints/rollback", {}, "subject_id"),
        ("POST", f"/api/subjects/1/fingerprints/{2**63}/promote", {}, "personalization_id"),
        ("POST", "/api/viewer/show", {"trial_id": 1, "t": float("nan")}, "t"),
        ("POST", "/api/viewer/show", {"trial_id": 1, "t": float("inf")}, "t"),
        ("POST", "/api/viewer/show", {"trial_id": 1, "t": 1e308}, "t"),
        ("POST", "/api/viewer/show", {"trial_id": 2**63, "t": 1.0}, "trial_id"),
        ("POST", "/api/viewer/focus", {"session_id": 2**63}, "session_id"),
        ("POST", "/api/uploads", {"filename": "x.csv", "size": 10**30, "subject_id": 1}, "size"),
        ("POST", "/api/uploads", {"filename": "x.csv", "size": 10, "subject_id": 2**63}, "subject_id"),
        ("POST", "/api/sessions", {"subject_id": 2**63}, "subject_id"),
        ("POST", "/api/sessions", {"subject_id": 1, "source": {"kind": "replay", "trial_id": 2**63}}, "trial_id"),
        ("POST", "/api/sessions", {"subject_id": 1, "source": {"kind": "simulated", "seed": 2**64}}, "seed"),
        ("PUT", f"/api/uploads/u?offset={2**63}", None, "offset"),
        ("GET", f"/api/sessions?subject_id={2**63}", None, "subject_id"),
    ],
)
def test_the_cases_found_by_hand_are_422_naming_the_field(
    client: TestClient, method: str, url: str, body: Any, where: str
) -> None:
    content = None if body is None else json.dumps(body)  # NaN and Infinity as Python writes them
    r = client.request(method, url, content=content, headers={"content-type": "application/json"})
    assert r.status_code == 422, (r.status_code, r.text)
    assert any(err["loc"][-1] == where for err in r.json()["detail"]), r.text


@pytest.mark.parametrize("session_id", ["abc", str(2**63), "-1", "0", "1.5", "١"])
def test_a_device_socket_with_a_session_id_that_is_not_one_is_closed_with_the_reason(
    client: TestClient, session_id: str
) -> None:
    with pytest.raises(WebSocketDisconnect) as closed:
        with client.websocket_connect(f"/ws/devices/{session_id}?token=x") as ws:
            ws.receive_text()
    assert closed.value.code == 1008
    assert "a session id is a whole number from 1 to 2**63-1" in closed.value.reason


def test_a_browser_stream_with_a_session_id_out_of_range_is_refused(client: TestClient) -> None:
    with pytest.raises(WebSocketDisconnect) as closed:
        with client.websocket_connect(f"/ws/sessions/{2**63}") as ws:
            ws.receive_text()
    assert closed.value.code == 1008


def test_an_upload_name_in_capitals_is_accepted(client: TestClient, tmp_path: Path) -> None:
    for name in ("X.CSV", "walk.Mcap", "t.PARQUET"):
        r = client.post("/api/uploads", json={"filename": name, "size": 10, "subject_id": 1})
        assert r.status_code == 201, (name, r.text)
        assert client.delete(f"/api/uploads/{r.json()['id']}").status_code == 204
    r = client.post("/api/uploads", json={"filename": "x.CSVX", "size": 10, "subject_id": 1})
    assert r.status_code == 422
