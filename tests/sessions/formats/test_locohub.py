"""Tests for gaitscope.sessions.formats.locohub: LocoHub tables in and out, and every way a table can be malformed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.formats import locohub
from gaitscope.sessions.formats.locohub import parse_task_info, read_table, write_table

SIGNALS = (schema.FOOT_ANGLE, schema.SHANK_ANGLE, schema.HEEL_FORWARD, schema.HEEL_UP, schema.ANKLE_MOMENT)


def _table(n: int = 6) -> pd.DataFrame:
    """A small valid table with every training column, two task_info values and an unknown column."""
    rng = np.random.default_rng(0)
    frame = pd.DataFrame(
        {
            schema.SUBJECT: ["01"] * n,
            schema.TASK: ["level_walking"] * n,
            schema.TASK_INFO: ["speed_m_s:1.2,incline_deg:0"] * (n // 2)
            + ["speed_m_s:0.8, incline_deg:-5"] * (n - n // 2),
            schema.STEP: np.arange(n) // 3,
            schema.PHASE_IPSI: np.tile([0.0, 50.0, 100.0], n // 3 + 1)[:n],
            "unknown_column": ["x"] * n,
        }
    )
    return _add_numeric_columns(frame, rng)


def _add_numeric_columns(frame: pd.DataFrame, rng: np.random.Generator) -> pd.DataFrame:
    """Add time and the rest of schema.TRAINING_COLUMNS (signals) as float columns."""
    frame[schema.TIME_S] = np.arange(len(frame)) * 0.01
    for column in (*SIGNALS, *schema.TRAINING_COLUMNS):
        if column not in frame.columns:
            frame[column] = rng.normal(size=len(frame))
    return frame


def _write_csv(path: Path, frame: pd.DataFrame) -> Path:
    frame.to_csv(path, index=False)
    return path


# --- parse_task_info ---------------------------------------------------------------------------


def test_parse_task_info_splits_pairs_and_strips_spaces() -> None:
    assert parse_task_info("speed_m_s:1.2, incline_deg : 5,note:a:b") == {
        "speed_m_s": "1.2",
        "incline_deg": "5",
        "note": "a:b",
    }


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "task_info is empty"),
        ("  ", "task_info is empty"),
        ("speed_m_s:1.2,incline_deg", "item 2 ('incline_deg') is not key:value"),
        ("speed_m_s:1.2,", "item 2 ('') is not key:value"),
        (":1.2", "item 1 (':1.2') has no key"),
        ("a:1,a:2", "key 'a' appears twice"),
    ],
)
def test_parse_task_info_says_what_is_wrong(text: str, message: str) -> None:
    with pytest.raises(ValueError) as info:
        parse_task_info(text)
    assert str(info.value) == message


# --- round trips ---------------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_round_trip_keeps_known_columns_and_adds_speed_and_incline(tmp_path: Path, suffix: str) -> None:
    frame = _table()
    path = tmp_path / f"table{suffix}"
    write_table(frame, path)
    table = read_table(path)

    expected = [c for c in locohub.KNOWN_COLUMNS if c in frame.columns] + [schema.INCLINE, schema.SPEED]
    assert list(table.columns) == expected
    assert "unknown_column" not in table.columns
    assert isinstance(table.index, pd.RangeIndex)
    assert table[schema.SUBJECT].tolist() == ["01"] * 6
    assert table[schema.STEP].dtype == np.int64
    assert table[schema.STEP].tolist() == [0, 0, 0, 1, 1, 1]
    for column in (*SIGNALS, schema.PHASE_IPSI, schema.TIME_S):
        assert table[column].dtype == np.float64
        np.testing.assert_array_equal(table[column].to_numpy(), frame[column].to_numpy())
    assert table[schema.SPEED].tolist() == [1.2, 1.2, 1.2, 0.8, 0.8, 0.8]
    assert table[schema.INCLINE].tolist() == [0.0, 0.0, 0.0, -5.0, -5.0, -5.0]


def test_speed_and_incline_columns_in_the_file_are_kept(tmp_path: Path) -> None:
    frame = _table()
    frame[schema.SPEED] = 9.0
    table = read_table(_write_csv(tmp_path / "t.csv", frame))
    assert table[schema.SPEED].tolist() == [9.0] * 6
    assert table[schema.INCLINE].tolist() == [0.0, 0.0, 0.0, -5.0, -5.0, -5.0]


def test_required_columns_can_be_chosen(tmp_path: Path) -> None:
    frame = pd.DataFrame({schema.SUBJECT: ["a", "b"], schema.THIGH_ANGLE: [0.1, 0.2], "other": [1, 2]})
    table = read_table(_write_csv(tmp_path / "t.csv", frame), required=(schema.THIGH_ANGLE,))
    assert list(table.columns) == [schema.SUBJECT, schema.THIGH_ANGLE]
    assert table[schema.THIGH_ANGLE].tolist() == [0.1, 0.2]


def test_numeric_text_in_parquet_is_converted(tmp_path: Path) -> None:
    frame = _table()
    frame[schema.FOOT_ANGLE] = ["0.5"] * 6
    path = tmp_path / "t.parquet"
    frame.to_parquet(path)  # with the index stored, which is not a known column
    table = read_table(path)
    assert table[schema.FOOT_ANGLE].dtype == np.float64
    assert table[schema.FOOT_ANGLE].tolist() == [0.5] * 6


def test_reads_a_million_rows_quickly(tmp_path: Path) -> None:
    n = 1_000_000
    frame = pd.DataFrame(
        {
            schema.SUBJECT: np.repeat(["s1", "s2"], n // 2),
            schema.TASK_INFO: np.tile(["speed_m_s:1.0,incline_deg:0", "speed_m_s:1.4,incline_deg:10"], n // 2),
            schema.STEP: np.arange(n) // 150,
            schema.PHASE_IPSI: np.tile(np.linspace(0.0, 100.0, 150), n // 150 + 1)[:n],
        }
    )
    _add_numeric_columns(frame, np.random.default_rng(1))
    path = tmp_path / "big.parquet"
    write_table(frame, path)
    table = read_table(path)  # seconds, not minutes: validation is vectorised
    assert len(table) == n
    assert table[schema.INCLINE].iloc[-1] == 10.0


# --- errors --------------------------------------------------------------------------------------


def _error(path: Path) -> str:
    with pytest.raises(DataFormatError) as info:
        read_table(path)
    return str(info.value)


def test_unsupported_suffix(tmp_path: Path) -> None:
    path = tmp_path / "t.xlsx"
    path.write_text("x")
    assert _error(path) == f"file {path}: unsupported file type '.xlsx'; expected .parquet or .csv"


def test_empty_csv(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    path.write_text("")
    assert _error(path) == f"file {path}: the file is empty"


def test_unreadable_parquet(tmp_path: Path) -> None:
    path = tmp_path / "t.parquet"
    path.write_bytes(b"not parquet at all")
    assert _error(path).startswith(f"file {path}: not a readable parquet file (")


def test_missing_required_columns_are_all_named(tmp_path: Path) -> None:
    path = _write_csv(tmp_path / "t.csv", _table().drop(columns=[schema.STEP, schema.ANKLE_MOMENT]))
    assert _error(path) == f"file {path}: missing required column(s) 'step', 'ankle_dorsiflexion_moment_ipsi_Nm'"


def test_no_rows(tmp_path: Path) -> None:
    path = _write_csv(tmp_path / "t.csv", _table().iloc[:0])
    assert _error(path) == f"file {path}: the table has no rows"


@pytest.mark.parametrize(
    ("cell", "message"),
    [
        ("abc", "not a number: 'abc'"),
        ("", "missing value"),
        ("nan", "NaN is not allowed"),
        ("-inf", "infinite value: '-inf'"),
    ],
)
def test_bad_numeric_cell_in_csv_names_column_and_line(tmp_path: Path, cell: str, message: str) -> None:
    frame = _table().astype({schema.ANKLE_MOMENT: object})
    frame.loc[3, schema.ANKLE_MOMENT] = cell
    frame.loc[5, schema.ANKLE_MOMENT] = "later"  # not reported: the first bad row is
    path = _write_csv(tmp_path / "t.csv", frame)
    assert _error(path) == f"file {path}, column '{schema.ANKLE_MOMENT}', row 5: {message}"


@pytest.mark.parametrize(("value", "message"), [(np.nan, "NaN is not allowed"), (np.inf, "infinite value: inf")])
def test_non_finite_cell_in_parquet_names_1_based_row(tmp_path: Path, value: float, message: str) -> None:
    frame = _table()
    frame.loc[2, schema.HEEL_UP] = value
    path = tmp_path / "t.parquet"
    write_table(frame, path)
    assert _error(path) == f"file {path}, column '{schema.HEEL_UP}', row 3: {message}"


def test_missing_text_cell(tmp_path: Path) -> None:
    frame = _table()
    frame.loc[1, schema.SUBJECT] = ""
    path = _write_csv(tmp_path / "t.csv", frame)
    assert _error(path) == f"file {path}, column 'subject', row 3: missing value"


def test_phase_out_of_range(tmp_path: Path) -> None:
    frame = _table()
    frame.loc[4, schema.PHASE_IPSI] = 100.5
    path = _write_csv(tmp_path / "t.csv", frame)
    assert _error(path) == f"file {path}, column 'phase_ipsi', row 6: phase must be within [0, 100], got 100.5"


def test_step_not_integral(tmp_path: Path) -> None:
    frame = _table().astype({schema.STEP: np.float64})
    frame.loc[0, schema.STEP] = 1.5
    path = tmp_path / "t.parquet"
    write_table(frame, path)
    assert _error(path) == f"file {path}, column 'step', row 1: step must be an integer, got 1.5"


@pytest.mark.parametrize(
    ("task_info", "message"),
    [
        ("speed_m_s:1.0", "no 'incline_deg' in 'speed_m_s:1.0'"),
        (
            "speed_m_s:fast,incline_deg:0",
            "'speed_m_s' is not a number ('fast') in 'speed_m_s:fast,incline_deg:0'",
        ),
        (
            "speed_m_s:1,incline_deg:inf",
            "'incline_deg' is not finite ('inf') in 'speed_m_s:1,incline_deg:inf'",
        ),
        ("speed_m_s=1", "item 1 ('speed_m_s=1') is not key:value in 'speed_m_s=1'"),
    ],
)
def test_bad_task_info_names_its_first_row(tmp_path: Path, task_info: str, message: str) -> None:
    frame = _table()
    frame.loc[[4, 5], schema.TASK_INFO] = task_info
    path = _write_csv(tmp_path / "t.csv", frame)
    assert _error(path) == f"file {path}, column 'task_info', row 6: {message}"


# --- write_table ---------------------------------------------------------------------------------


def test_write_rejects_unknown_suffix(tmp_path: Path) -> None:
    with pytest.raises(ValueError) as info:
        write_table(_table(), tmp_path / "t.txt")
    assert str(info.value) == f"file {tmp_path / 't.txt'}: unsupported file type '.txt'; expected .parquet or .csv"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("suffix", "method"), [(".parquet", "to_parquet"), (".csv", "to_csv")])
def test_failed_write_leaves_no_file_and_keeps_the_old_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, suffix: str, method: str
) -> None:
    def write_half_then_fail(self: pd.DataFrame, path: Path, **kwargs: object) -> None:
        Path(path).write_bytes(b"half a file")
        raise OSError("disk full")

    new, old = tmp_path / f"new{suffix}", tmp_path / f"old{suffix}"
    write_table(_table(), old)
    before = old.read_bytes()
    monkeypatch.setattr(pd.DataFrame, method, write_half_then_fail)
    for path in (new, old):
        with pytest.raises(OSError, match="disk full"):
            write_table(_table(), path)
    assert sorted(p.name for p in tmp_path.iterdir()) == [old.name]  # no temporary file left behind
    assert old.read_bytes() == before


def test_write_replaces_an_existing_file(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    path.write_text("old")
    write_table(_table(), path)
    assert len(read_table(path)) == 6
    assert [p.name for p in tmp_path.iterdir()] == ["t.csv"]
