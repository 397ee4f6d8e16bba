"""Property-based tests of the replay CSV reader: on any bytes, valid arrays or a ``DataFormatError``
naming the file (and the row or column where one is at fault), never another exception; and the fast
Arrow path returns exactly what the validating Python reader returns."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.formats import replay_io
from gaitscope.sessions.formats.replay_io import MAX_PERIOD_S, MIN_PERIOD_S, ReplayInput, read_replay_csv

PROPERTY = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
KNOWN = (schema.REPLAY_TIME, *schema.REPLAY_SIGNALS, schema.REPLAY_HEEL_STRIKE)

#: Cells: numbers as people and programs write them, and the ways they go wrong.
NUMBER = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
    st.floats(-1e3, 1e3).map(lambda v: f"{v:.6f}"),
    st.floats(-1e3, 1e3).map(lambda v: f"{v:.17g}"),
    st.integers(-(10**20), 10**20).map(str),
    st.integers(0, 30).flatmap(lambda p: st.decimals(allow_nan=False, allow_infinity=False, places=p)).map(str),
    st.sampled_from(["0", "1", "-0", "1.", ".5", "+2", "1e5", "1E-5", "0.0", "1.0", "00.10", "5e-324", "1e-400"]),
)
CELL = st.one_of(
    NUMBER,
    NUMBER.map(lambda v: f" {v} "),
    st.sampled_from(["", " ", "nan", "NaN", "inf", "-inf", "NA", "null", "abc", "1_0", "0x10", '"1"', "1,5", "1\t"]),
    st.text(max_size=6),
)
HEADER_NAME = st.one_of(st.sampled_from(KNOWN), st.sampled_from(["note", " time_s ", "", "x"]), st.text(max_size=5))


@st.composite
def csv_files(draw: st.DrawFn) -> bytes:
    """Replay-CSV-like files: a header of known and other names, rows of cells, odd line ends."""
    names = draw(st.lists(HEADER_NAME, min_size=1, max_size=5))
    if draw(st.booleans()):
        names = [schema.REPLAY_TIME, draw(st.sampled_from(schema.REPLAY_ANGLES)), *names]
    n_rows = draw(st.integers(0, 8))
    width = len(names)
    rows = []
    t = draw(st.floats(-1e3, 1e3))
    for _ in range(n_rows):
        cells = draw(st.lists(CELL, min_size=width, max_size=width))
        if draw(st.integers(0, 9)) == 0:  # a row of the wrong length
            cells = cells[: draw(st.integers(0, width))] + draw(st.lists(CELL, max_size=2))
        for j, name in enumerate(names):  # mostly plausible times and heel strikes
            if j < len(cells) and name == schema.REPLAY_TIME and draw(st.integers(0, 4)):
                t += draw(st.sampled_from([0.01, 0.01, 0.02, 0.0, -0.01, 2.0]))
                cells[j] = repr(t)
            elif j < len(cells) and name == schema.REPLAY_HEEL_STRIKE and draw(st.integers(0, 4)):
                cells[j] = draw(st.sampled_from(["0", "1", "1.0", "0.0"]))
        rows.append(",".join(cells))
        if draw(st.integers(0, 9)) == 0:
            rows.append(draw(st.sampled_from(["", " ", ",,"])))
    newline = draw(st.sampled_from(["\n", "\r\n", "\r"]))
    text = newline.join([",".join(names), *rows]) + draw(st.sampled_from(["", newline]))
    data = text.encode("utf-8", errors="surrogatepass")
    return (b"\xef\xbb\xbf" if draw(st.integers(0, 9)) == 0 else b"") + data


@st.composite
def plain_files(draw: st.DrawFn) -> bytes:
    """Mostly valid replay CSVs (numbers written every which way, an ignored text column, blank lines),
    half of them with one thing wrong."""
    signals = draw(st.lists(st.sampled_from(schema.REPLAY_SIGNALS), min_size=1, max_size=6, unique=True))
    if not any(a in signals for a in schema.REPLAY_ANGLES):
        signals.append(draw(st.sampled_from(schema.REPLAY_ANGLES)))
    names = [schema.REPLAY_TIME, *signals]
    if draw(st.booleans()):
        names.append(schema.REPLAY_HEEL_STRIKE)
    if draw(st.booleans()):
        names.insert(draw(st.integers(0, len(names))), "note")
    names = draw(st.permutations(names))
    rows: list[list[str]] = []
    t = draw(st.floats(-1e3, 1e3))
    for _ in range(draw(st.integers(2, 12))):
        t += draw(st.sampled_from([0.01, 0.01, 0.005, 0.02]))
        row = []
        for name in names:
            if name == schema.REPLAY_TIME:
                row.append(draw(st.sampled_from(["{!r}", "{:.17g}", "{:.10f}"])).format(t))
            elif name == schema.REPLAY_HEEL_STRIKE:
                row.append(draw(st.sampled_from(["0", "1", "0.0", "1.0", "1e0"])))
            elif name == "note":
                row.append(draw(st.sampled_from(["", "left", "a b", "x;y"])))
            else:
                row.append(draw(NUMBER))
        rows.append(row)
    lines = [",".join(names), *(",".join(r) for r in rows)]
    if draw(st.booleans()):  # one thing wrong, or merely unusual
        i = draw(st.integers(1, len(lines) - 1))
        change = draw(st.sampled_from(["cell", "short", "blank", "quote"]))
        cells = lines[i].split(",")
        if change == "cell":
            cells[draw(st.integers(0, len(cells) - 1))] = draw(CELL)
        elif change == "short":
            cells = cells[:-1]
        elif change == "quote":
            j = draw(st.integers(0, len(cells) - 1))
            cells[j] = f'"{cells[j]}"'
        lines[i] = "" if change == "blank" else ",".join(cells)
    newline = draw(st.sampled_from(["\n", "\r\n"]))
    return (newline.join(lines) + newline).encode("utf-8", errors="surrogatepass")


def _check_valid(data: ReplayInput) -> None:
    t = data.time_s
    assert t.dtype == np.float64 and t.ndim == 1 and t.size >= 2
    assert np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)
    assert MIN_PERIOD_S <= float(np.median(np.diff(t))) <= MAX_PERIOD_S
    assert data.signals and list(data.signals) == [s for s in schema.REPLAY_SIGNALS if s in data.signals]
    assert any(a in data.signals for a in schema.REPLAY_ANGLES)
    for values in data.signals.values():
        assert values.dtype == np.float64 and values.shape == t.shape and np.all(np.isfinite(values))
    if data.heel_strike is not None:
        assert data.heel_strike.dtype == np.bool_ and data.heel_strike.shape == t.shape


def _check_error(err: DataFormatError, path: Path, data: bytes) -> None:
    assert err.file == str(path) and str(err).startswith(f"file {path}")
    if err.row is not None:
        assert 1 <= err.row <= max(1, data.count(b"\n") + data.count(b"\r") + 1)
        assert f"row {err.row}" in str(err)
    if err.column is not None:
        assert err.column in KNOWN and f"column {err.column!r}" in str(err)


def _read(path: Path) -> ReplayInput | DataFormatError:
    try:
        return read_replay_csv(path)
    except DataFormatError as err:
        return err


def _same(a: ReplayInput | DataFormatError, b: ReplayInput | DataFormatError) -> bool:
    if isinstance(a, DataFormatError) or isinstance(b, DataFormatError):
        return str(a) == str(b)
    same_hs = (a.heel_strike is None and b.heel_strike is None) or (
        a.heel_strike is not None and b.heel_strike is not None and np.array_equal(a.heel_strike, b.heel_strike)
    )
    return (
        np.array_equal(a.time_s, b.time_s)
        and a.signals.keys() == b.signals.keys()
        and all(np.array_equal(a.signals[k], b.signals[k]) for k in a.signals)
        and same_hs
    )


@PROPERTY
@given(data=st.one_of(st.binary(max_size=300), st.text(max_size=300).map(str.encode), csv_files()))
@example(data=b"time_s,foot_angle_deg\n0,1\n0.01,2\n")
@example(data=b"time_s,foot_angle_deg\n0,1\n0.01,\n")
@example(data=b"\xff\xfe")
def test_any_bytes_give_valid_arrays_or_a_data_format_error(tmp_path: Path, data: bytes) -> None:
    path = tmp_path / "trial.csv"
    path.write_bytes(data)
    result = _read(path)  # any other exception fails the test
    if isinstance(result, DataFormatError):
        _check_error(result, path, data)
    else:
        _check_valid(result)


@PROPERTY
@given(data=st.one_of(plain_files(), csv_files()))
def test_the_fast_reader_returns_what_the_validating_reader_returns(tmp_path: Path, data: bytes) -> None:
    path = tmp_path / "trial.csv"
    path.write_bytes(data)
    try:
        validated: ReplayInput | DataFormatError = replay_io._read_validated(path, str(path), replay_io.DEFAULT_NEEDS)
    except DataFormatError as err:
        validated = err
    assert _same(_read(path), validated)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    values=st.lists(
        st.one_of(
            st.floats(allow_nan=False, allow_infinity=False),
            st.floats(allow_nan=False, allow_infinity=False, allow_subnormal=True, width=64).map(lambda v: v / 3),
        ),
        min_size=2,
        max_size=40,
    ),
    fmt=st.sampled_from(["{!r}", "{:.17g}", "{:.25e}", "{:.3f}", "{:.40f}"]),
)
def test_numbers_parse_to_the_same_bits_on_both_paths(tmp_path: Path, values: list[float], fmt: str) -> None:
    """Arrow's decimal parser rounds as Python's ``float`` does, however many digits a cell has."""
    path = tmp_path / "trial.csv"
    rows = "".join(f"{0.01 * k!r},{fmt.format(v)}\n" for k, v in enumerate(values))
    path.write_text("time_s,foot_angle_deg\n" + rows)
    fast = replay_io._read_plain(path, str(path), replay_io.DEFAULT_NEEDS)
    assert fast is not None  # a plain file takes the fast path
    expected = np.array([float(fmt.format(v)) for v in values])
    np.testing.assert_array_equal(fast.signals["foot_angle_deg"].view(np.int64), expected.view(np.int64))


@pytest.mark.parametrize(
    "text",
    [
        'time_s,foot_angle_deg\n0,1\n0.01,"2"\n',  # quoted: the validating reader
        "time_s,foot_angle_deg\r0,1\r0.01,2\r",  # old Mac line ends
        "time_s,foot_angle_deg,note\n0,1,é\n0.01,2,x\n",  # not ASCII
        "time_s,foot_angle_deg\n0,1\n0.01,nan\n",  # a bad cell: the validating reader names it
    ],
)
def test_files_the_fast_reader_leaves_to_the_validating_one(tmp_path: Path, text: str) -> None:
    path = tmp_path / "trial.csv"
    path.write_bytes(text.encode())
    assert replay_io._read_plain(path, str(path), replay_io.DEFAULT_NEEDS) is None
