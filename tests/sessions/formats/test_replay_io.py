"""Tests for sessions.formats.replay_io: the replay CSV in and out, and every way an input can be malformed."""

from __future__ import annotations

import csv
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.formats.replay_io import ReplayInput, read_replay_csv, write_replay_output

GOOD = """time_s,foot_angle_deg,note,heel_strike,shank_vel_dps
0.00,-10.5,a,1,3
0.01,-9.25,b,0,4.5e1
0.02,-8,c,0,-1
"""


def _write(tmp_path: Path, text: str, name: str = "trial.csv") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _error(path: Path) -> str:
    with pytest.raises(DataFormatError) as info:
        read_replay_csv(path)
    return str(info.value)


# --- reading -------------------------------------------------------------------------------------


def test_reads_present_columns_and_ignores_unknown_ones(tmp_path: Path) -> None:
    replay = read_replay_csv(_write(tmp_path, GOOD))
    assert isinstance(replay, ReplayInput)
    assert replay.time_s.dtype == np.float64
    assert replay.time_s.tolist() == [0.0, 0.01, 0.02]
    assert list(replay.signals) == ["foot_angle_deg", "shank_vel_dps"]  # schema order, not file order
    assert replay.signals["foot_angle_deg"].tolist() == [-10.5, -9.25, -8.0]
    assert replay.signals["shank_vel_dps"].tolist() == [3.0, 45.0, -1.0]
    assert replay.heel_strike is not None
    assert replay.heel_strike.dtype == np.bool_
    assert replay.heel_strike.tolist() == [True, False, False]


def test_heel_strike_is_optional_and_blank_lines_and_bom_are_tolerated(tmp_path: Path) -> None:
    text = "\ufeff time_s , shank_angle_deg\n0,1\n\n1,2\n"
    replay = read_replay_csv(_write(tmp_path, text))
    assert replay.heel_strike is None
    assert replay.time_s.tolist() == [0.0, 1.0]
    assert replay.signals == {"shank_angle_deg": pytest.approx(np.array([1.0, 2.0]))}


def test_reads_sixty_thousand_rows(tmp_path: Path) -> None:
    n = 60_000
    t = np.arange(n) / 100.0
    frame = pd.DataFrame({"time_s": t, **{s: np.sin(t) for s in schema.REPLAY_SIGNALS}, "heel_strike": 0})
    path = tmp_path / "long.csv"
    frame.to_csv(path, index=False)
    replay = read_replay_csv(path)
    np.testing.assert_array_equal(replay.time_s, t)
    assert list(replay.signals) == list(schema.REPLAY_SIGNALS)
    np.testing.assert_array_equal(replay.signals["heel_up_m"], np.sin(t))


# --- reading: errors -----------------------------------------------------------------------------


def test_empty_file(tmp_path: Path) -> None:
    path = _write(tmp_path, "")
    assert _error(path) == f"file {path}: the file is empty"


def test_empty_header(tmp_path: Path) -> None:
    path = _write(tmp_path, ",\n1,2\n")
    assert _error(path) == f"file {path}, row 1: the header row is empty"


def test_missing_time_column(tmp_path: Path) -> None:
    path = _write(tmp_path, "t,foot_angle_deg\n0,1\n1,2\n")
    assert _error(path) == f"file {path}, column 'time_s', row 1: missing required column"


def test_no_angle_column(tmp_path: Path) -> None:
    path = _write(tmp_path, "time_s,foot_vel_dps\n0,1\n1,2\n")
    assert _error(path) == (
        f"file {path}, row 1: the file's channels cannot feed the estimators asked for: "
        "phase_ekf needs foot_angle_deg or shank_angle_deg"
    )


def test_no_channel_column_says_how_columns_are_named(tmp_path: Path) -> None:
    path = _write(tmp_path, "time_s,Knee Angle Deg,force\n0,1,2\n1,2,3\n")
    assert _error(path).startswith(
        f"file {path}, row 1: no sensor channel column (Knee Angle Deg: names are lower case, with underscores); "
    )


def test_every_channel_column_is_read_and_the_others_are_listed(tmp_path: Path) -> None:
    header = "time_s,shank_angle_deg,thigh_angle_deg,knee_angle_deg,foot_contact,notes,"
    text = header + "\n0,1,2,3,1,4,5\n0.01,2,3,4,0,5,6\n"
    data = read_replay_csv(_write(tmp_path, text))
    assert list(data.signals) == ["shank_angle_deg", "thigh_angle_deg", "knee_angle_deg", "foot_contact"]
    assert data.signals["foot_contact"].tolist() == [1.0, 0.0] and data.ignored == ("notes", "(column 7)")
    bad = _write(tmp_path, "time_s,shank_angle_deg,foot_contact\n0,1,1\n0.01,2,2\n")
    assert _error(bad) == f"file {bad}, column 'foot_contact', row 3: must be 0 or 1, got '2'"


def test_repeated_column(tmp_path: Path) -> None:
    path = _write(tmp_path, "time_s,foot_angle_deg,x,x,foot_angle_deg\n0,1,,,1\n1,2,,,2\n")
    assert _error(path) == f"file {path}, column 'foot_angle_deg', row 1: column name appears twice"


@pytest.mark.parametrize(("line", "found"), [("0.03,1,d,0,5,6", 6), ("0.03,1", 2)])
def test_wrong_number_of_fields(tmp_path: Path, line: str, found: int) -> None:
    path = _write(tmp_path, GOOD + line + "\n")
    assert _error(path) == f"file {path}, row 5: expected 5 fields, found {found}"


@pytest.mark.parametrize("rows", ["", "0,1\n"])
def test_fewer_than_two_rows(tmp_path: Path, rows: str) -> None:
    path = _write(tmp_path, "time_s,foot_angle_deg\n" + rows)
    assert _error(path) == f"file {path}: need at least 2 data rows, found {rows.count(chr(10))}"


@pytest.mark.parametrize(
    ("cell", "message"),
    [
        ("abc", "not a number: 'abc'"),
        (" ", "empty cell"),
        ("", "empty cell"),
        ("nan", "NaN (nan) is not allowed"),
        ("-inf", "infinite value (-inf) is not allowed"),
    ],
)
def test_bad_cell_names_line_and_column(tmp_path: Path, cell: str, message: str) -> None:
    text = GOOD.replace("0.01,-9.25,b,0,4.5e1", f"0.01,-9.25,b,0,{cell}").replace("0.02,-8", "0.02,oops")
    path = _write(tmp_path, text)
    assert _error(path) == f"file {path}, column 'shank_vel_dps', row 3: {message}"


def test_earliest_bad_line_wins_over_column_order(tmp_path: Path) -> None:
    text = GOOD.replace("0.02,-8", "x,-8").replace("0.01,-9.25", "0.01,y")
    path = _write(tmp_path, text)
    assert _error(path) == f"file {path}, column 'foot_angle_deg', row 3: not a number: 'y'"


def test_unknown_columns_are_not_checked(tmp_path: Path) -> None:
    replay = read_replay_csv(_write(tmp_path, GOOD.replace(",b,", ",not a number,")))
    assert replay.time_s.tolist() == [0.0, 0.01, 0.02]


@pytest.mark.parametrize("cell", ["2", "0.5", "-1"])
def test_heel_strike_must_be_zero_or_one(tmp_path: Path, cell: str) -> None:
    path = _write(tmp_path, GOOD.replace("0.02,-8,c,0", f"0.02,-8,c,{cell}"))
    assert _error(path) == f"file {path}, column 'heel_strike', row 4: must be 0 or 1, got '{cell}'"


@pytest.mark.parametrize(
    ("times", "message"),
    [
        (("0.0", "1.240", "1.23"), "time goes backwards (1.23 after 1.240)"),
        (("0", "1", "1.0"), "time repeats (1.0 after 1)"),
    ],
)
def test_time_must_strictly_increase(tmp_path: Path, times: tuple[str, ...], message: str) -> None:
    text = "time_s,foot_angle_deg\n" + "".join(f"{t},0\n" for t in times) + "0.5,0\n"
    path = _write(tmp_path, text)
    assert _error(path) == f"file {path}, column 'time_s', row 4: {message}"


# --- writing -------------------------------------------------------------------------------------


def _output(n: int = 3) -> dict[str, np.ndarray]:
    columns = {c: np.linspace(0.0, 1.0, n) / 3.0 for c in schema.REPLAY_OUTPUT}
    columns["heel_strike"] = np.array([True] + [False] * (n - 1))
    columns["tbe_phase"] = np.array([np.nan] + [0.1] * (n - 1))
    return columns


def test_output_round_trips_at_full_precision(tmp_path: Path) -> None:
    path = tmp_path / "out.csv"
    columns = dict(reversed(list(_output().items())))  # the mapping's order does not matter
    write_replay_output(path, columns)
    lines = path.read_text().splitlines()
    assert lines[0] == ",".join(schema.REPLAY_OUTPUT)
    assert lines[1] == "0.0,0.0,0.0,0.0,0.0,0.0,1,nan"
    assert lines[2].split(",")[-2:] == ["0", "0.1"]
    back = pd.read_csv(path)
    assert back["heel_strike"].dtype == np.int64
    for column in schema.REPLAY_OUTPUT:
        np.testing.assert_array_equal(back[column].to_numpy(), np.asarray(columns[column], dtype=np.float64))
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            lambda c: c.pop("phase"),
            "replay output columns: missing ['phase'], unexpected []",
        ),
        (
            lambda c: c.update(extra=np.zeros(3)),
            "replay output columns: missing [], unexpected ['extra']",
        ),
        (
            lambda c: c.update(heel_strike=np.array([0, 2, 1])),
            "replay output column 'heel_strike' must hold only 0/1",
        ),
    ],
)
def test_output_rejects_bad_columns(
    tmp_path: Path, change: Callable[[dict[str, np.ndarray]], object], message: str
) -> None:
    columns = _output()
    change(columns)
    with pytest.raises(ValueError) as info:
        write_replay_output(tmp_path / "out.csv", columns)
    assert str(info.value) == message
    assert list(tmp_path.iterdir()) == []


def test_output_rejects_unequal_lengths(tmp_path: Path) -> None:
    columns = _output()
    columns["phase"] = np.zeros(4)
    with pytest.raises(ValueError, match=r"^replay output columns must be 1-D and of equal length, got shapes "):
        write_replay_output(tmp_path / "out.csv", columns)


def test_failed_write_leaves_no_file_and_keeps_the_old_one(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    class HalfThenFail:  # a csv writer on a disk that fills up in the middle of the header
        def __init__(self, file: Any, **kwargs: object) -> None:
            self.file = file

        def writerow(self, row: object) -> None:
            self.file.write("time_s,pha")
            raise OSError("disk full")

    old, new = tmp_path / "old.csv", tmp_path / "new.csv"
    write_replay_output(old, _output())
    before = old.read_bytes()
    monkeypatch.setattr(csv, "writer", HalfThenFail)
    for path in (old, new):
        with pytest.raises(OSError, match="disk full"):
            write_replay_output(path, _output())
    assert [p.name for p in tmp_path.iterdir()] == ["old.csv"]
    assert old.read_bytes() == before
