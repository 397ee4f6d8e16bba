"""``ReplayOutput``: the replay output CSV written in parts, formatted exactly as Python's ``repr``,
and atomic whatever fails (a part's formatting, the caller's body)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gaitscope.sessions import schema
from gaitscope.sessions.formats import _fastcsv
from gaitscope.sessions.formats.replay_io import ReplayOutput, write_replay_output


def _columns(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    columns: dict[str, np.ndarray] = {c: rng.normal(0.0, 10.0, n) for c in schema.REPLAY_OUTPUT}
    columns["heel_strike"] = rng.random(n) < 0.1
    return columns


def _part(columns: dict[str, np.ndarray], a: int, b: int) -> dict[str, np.ndarray]:
    return {c: v[a:b] for c, v in columns.items()}


def test_parts_make_the_same_file_as_one_write(tmp_path: Path) -> None:
    columns = _columns(1000)
    write_replay_output(tmp_path / "whole.csv", columns)
    with ReplayOutput(tmp_path / "parts.csv") as output:
        for a, b in [(0, 1), (1, 400), (400, 400), (400, 1000)]:
            output.add(_part(columns, a, b))
    assert (tmp_path / "parts.csv").read_bytes() == (tmp_path / "whole.csv").read_bytes()


def test_floats_are_written_as_python_writes_them(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    odd = [0.0, -0.0, 1.0, 100.0, 1e15, 1e16, 1e17, 1e-4, 1e-5, 1.5e-5, 1e-7, 5e-324, 0.1, 1 / 3, 1e22, -1e-300]
    special = [np.inf, -np.inf, np.nan, 1.7976931348623157e308, 9999999999999998.0, 123456789012345.6]
    bits = rng.integers(-(2**63), 2**63 - 1, 3000, dtype=np.int64).view(np.float64)
    values = np.concatenate([odd, special, bits, rng.random(3000) * 100.0])
    lines = bytes(_fastcsv.format_rows([values, (values > 0).astype(np.int64)])).decode().splitlines()
    expected = [f"{float(v)!r},{int(v > 0)}" for v in values]
    assert lines == expected


def test_a_part_that_fails_to_format_leaves_no_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    old, new = tmp_path / "old.csv", tmp_path / "new.csv"
    write_replay_output(old, _columns(10))
    before = old.read_bytes()
    real = _fastcsv.format_rows
    calls: list[int] = []

    def fail_on_the_second(values: list[np.ndarray]) -> memoryview:
        calls.append(1)
        if len(calls) == 2:
            raise OSError("disk full")
        return real(values)

    monkeypatch.setattr(_fastcsv, "format_rows", fail_on_the_second)
    for path in (old, new):
        calls.clear()
        with pytest.raises(OSError, match="disk full"), ReplayOutput(path) as output:
            output.add(_columns(10))
            output.add(_columns(10))
    assert [p.name for p in tmp_path.iterdir()] == ["old.csv"]
    assert old.read_bytes() == before


def test_an_error_in_the_with_block_leaves_no_file(tmp_path: Path) -> None:
    path = tmp_path / "out.csv"
    with pytest.raises(ValueError, match="estimates went wrong"), ReplayOutput(path) as output:
        output.add(_columns(10))
        raise ValueError("estimates went wrong")
    with pytest.raises(ValueError, match="must hold only 0/1"), ReplayOutput(path) as output:
        output.add(_columns(10))
        output.add({**_columns(3), "heel_strike": np.array([0, 1, 2])})
    assert list(tmp_path.iterdir()) == []


def test_add_outside_the_with_block_is_refused(tmp_path: Path) -> None:
    output = ReplayOutput(tmp_path / "out.csv")
    with pytest.raises(RuntimeError, match="outside its with block"):
        output.add(_columns(3))
    with output:
        output.add(_columns(3))
    with pytest.raises(RuntimeError, match="outside its with block"):
        output.add(_columns(3))
    assert (tmp_path / "out.csv").read_text().count("\n") == 4
