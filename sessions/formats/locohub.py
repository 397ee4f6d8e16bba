"""Read and write tables in the LocoHub standard (jmontp/LocoHub).

A LocoHub table has one row per sample: metadata columns (``subject``, ``task``, ``task_info``, ...),
``step`` (stride index), ``phase_ipsi`` (percent of the ipsilateral gait cycle) and signal columns
such as ``thigh_sagittal_angle_ipsi_rad``. Every column name comes from :mod:`gaitscope.sessions.schema`.
Files are parquet or CSV, chosen by the suffix.

:func:`read_table` validates a table with vectorised checks (a million rows take about a second) and
raises :class:`~gaitscope.sessions.errors.DataFormatError` naming the file, the column and the row of the first
problem. :func:`write_table` writes atomically: the target is replaced only once the new file is
complete.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Final

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.files import atomic_output

__all__ = ["CHANNELS_OF", "KNOWN_COLUMNS", "STRING_COLUMNS", "parse_task_info", "read_table", "write_table"]

#: Columns whose cells are text; every other known column is numeric.
STRING_COLUMNS: Final = (
    schema.SUBJECT,
    schema.SUBJECT_METADATA,
    schema.TASK,
    schema.TASK_ID,
    schema.TASK_INFO,
)

#: Every LocoHub column gaitscope knows, in the order :func:`read_table` returns them. Other columns
#: of a file are dropped on reading.
KNOWN_COLUMNS: Final = (
    *schema.METADATA_COLUMNS,
    schema.TIME_S,
    schema.THIGH_ANGLE,
    schema.SHANK_ANGLE,
    schema.FOOT_ANGLE,
    schema.HIP_ANGLE,
    schema.KNEE_ANGLE,
    schema.ANKLE_ANGLE,
    schema.HIP_ANGLE_CONTRA,
    schema.HEEL_FORWARD,
    schema.HEEL_UP,
    schema.ANKLE_MOMENT,
    *schema.COM_POSITION,
    *schema.COM_VELOCITY,
    schema.HEEL_STRIKE,
    schema.TOE_OFF,
    schema.HEEL_STRIKE_CONTRA,
    schema.STEP_LENGTH,
    schema.PHASE_RATE,
    schema.STRIDE_LENGTH,
    schema.INCLINE,
    schema.SPEED,
    # both legs, pelvis, ground reaction forces, centre of mass over the stance foot (schema version 2)
    schema.THIGH_ANGLE_CONTRA,
    schema.SHANK_ANGLE_CONTRA,
    schema.FOOT_ANGLE_CONTRA,
    schema.KNEE_ANGLE_CONTRA,
    schema.ANKLE_ANGLE_CONTRA,
    schema.PELVIS_ANGLE,
    schema.VERTICAL_GRF,
    schema.VERTICAL_GRF_CONTRA,
    schema.STEP_LENGTH_CONTRA,
    *schema.COM_STANCE_POSITION,
)

_RAD: Final = 180.0 / math.pi
#: Each LocoHub signal a sensor channel carries: ``column: (channel, scale)``, the channel's value being the
#: column's times ``scale``. Angles from radians to degrees, both standards (+) the same way (sagittal
#: angles seen from the subject's right, flexion and dorsiflexion (+)); the centre of mass relative to the
#: stance foot, lateral (+) to the left in LocoHub and to the right in gaitscope. The centre of mass's velocity
#: (``com_*_velocity_m_s``) is the channel's on level ground; on a slope the stance foot moves along it with the
#: belt and the channel differs (not corrected here: the table does not say the belt speed per sample).
#: The other LocoHub columns carry no sensor channel (the ankle moment, the pelvis tilt, toe-offs, step lengths
#: per stride, the ground truth: phase, speed, incline) and are listed as not read.
CHANNELS_OF: Final[dict[str, tuple[str, float]]] = {
    schema.FOOT_ANGLE: ("foot_angle_deg", _RAD),
    schema.SHANK_ANGLE: ("shank_angle_deg", _RAD),
    schema.THIGH_ANGLE: ("thigh_angle_deg", _RAD),
    schema.FOOT_ANGLE_CONTRA: ("foot_angle_contra_deg", _RAD),
    schema.SHANK_ANGLE_CONTRA: ("shank_angle_contra_deg", _RAD),
    schema.THIGH_ANGLE_CONTRA: ("thigh_angle_contra_deg", _RAD),
    schema.HIP_ANGLE: ("hip_angle_deg", _RAD),
    schema.KNEE_ANGLE: ("knee_angle_deg", _RAD),
    schema.ANKLE_ANGLE: ("ankle_angle_deg", _RAD),
    schema.HIP_ANGLE_CONTRA: ("hip_angle_contra_deg", _RAD),
    schema.KNEE_ANGLE_CONTRA: ("knee_angle_contra_deg", _RAD),
    schema.ANKLE_ANGLE_CONTRA: ("ankle_angle_contra_deg", _RAD),
    schema.HEEL_FORWARD: ("heel_forward_m", 1.0),
    schema.HEEL_UP: ("heel_up_m", 1.0),
    schema.VERTICAL_GRF: ("foot_force_N", 1.0),
    schema.VERTICAL_GRF_CONTRA: ("foot_force_contra_N", 1.0),
    schema.COM_STANCE_POSITION[0]: ("com_forward_m", 1.0),
    schema.COM_STANCE_POSITION[1]: ("com_lateral_m", -1.0),
    schema.COM_STANCE_POSITION[2]: ("com_up_m", 1.0),
    schema.COM_VELOCITY[0]: ("com_forward_vel_m_s", 1.0),
    schema.COM_VELOCITY[1]: ("com_lateral_vel_m_s", -1.0),
    schema.COM_VELOCITY[2]: ("com_up_vel_m_s", 1.0),
}

_KNOWN_SET: Final = frozenset(KNOWN_COLUMNS)
_STRING_SET: Final = frozenset(STRING_COLUMNS)
_SUFFIXES: Final = (".parquet", ".csv")
#: task_info keys that become the numeric columns of the same name.
_TASK_INFO_NUMBERS: Final = (schema.SPEED, schema.INCLINE)


def parse_task_info(text: str) -> dict[str, str]:
    """Parse a LocoHub ``key:value,key:value`` string.

    Whitespace around keys and values is removed; a value may itself contain ``:``.

    Example:
        ``parse_task_info("speed_m_s:1.2,incline_deg:5")`` is ``{"speed_m_s": "1.2", "incline_deg": "5"}``.

    Raises:
        ValueError: the text is empty, an item has no ``:`` or no key, or a key repeats.
    """
    if not text.strip():
        raise ValueError("task_info is empty")
    out: dict[str, str] = {}
    for position, item in enumerate(text.split(","), start=1):
        key, sep, value = item.partition(":")
        key, value = key.strip(), value.strip()
        if not sep:
            raise ValueError(f"item {position} ({item.strip()!r}) is not key:value")
        if not key:
            raise ValueError(f"item {position} ({item.strip()!r}) has no key")
        if key in out:
            raise ValueError(f"key {key!r} appears twice")
        out[key] = value
    return out


def read_table(path: str | Path, required: Sequence[str] = schema.TRAINING_COLUMNS) -> pd.DataFrame:
    """Read and validate a LocoHub table.

    Args:
        path: a ``.parquet`` or ``.csv`` file.
        required: columns the table must have.

    Returns:
        The known columns of the file (see :data:`KNOWN_COLUMNS`, in that order) with a fresh
        ``RangeIndex``: text columns as strings, ``step`` as int64, every other column float64. When
        the file has ``task_info`` but no ``speed_m_s`` / ``incline_deg`` column, those are added from it.

    Raises:
        DataFormatError: unsupported suffix, unreadable file, missing required columns, no rows, or a
            bad cell: a numeric cell that is empty, not a number, NaN or infinite; ``phase_ipsi``
            outside [0, 100]; a non-integral ``step``; a ``task_info`` without numeric ``speed_m_s``
            and ``incline_deg``; an empty text cell. Rows are file line numbers for CSV (header is
            line 1; a quoted cell spanning lines would shift them) and 1-based rows for parquet.
    """
    path = Path(path)
    name = str(path)
    suffix = path.suffix.lower()
    if suffix not in _SUFFIXES:
        raise DataFormatError(f"unsupported file type {path.suffix!r}; expected .parquet or .csv", file=name)
    if suffix == ".csv":
        raw, first_row = _read_csv(path, name), 2
    else:
        raw, first_row = _read_parquet(path, name), 1

    missing = [c for c in required if c not in raw.columns]
    if missing:
        listed = ", ".join(repr(c) for c in missing)
        raise DataFormatError(f"missing required column(s) {listed}", file=name)
    if len(raw) == 0:
        raise DataFormatError("the table has no rows", file=name)

    out: dict[str, Any] = {}
    for column in KNOWN_COLUMNS:
        if column not in raw.columns:
            continue
        cells = raw[column].reset_index(drop=True)
        if column in _STRING_SET:
            out[column] = _text_column(cells, name, column, first_row)
        else:
            out[column] = _numeric_column(cells, name, column, first_row)

    if schema.TASK_INFO in out:
        derived = _task_info_numbers(out[schema.TASK_INFO], name, first_row)
        for column, values in derived.items():
            out.setdefault(column, values)
    ordered = {column: out[column] for column in KNOWN_COLUMNS if column in out}
    return pd.DataFrame(ordered, index=pd.RangeIndex(len(raw)))


def write_table(frame: pd.DataFrame, path: str | Path) -> None:
    """Write ``frame`` (without its index) as parquet or CSV, chosen by the suffix of ``path``.

    The file is written to a temporary file in the same directory and moved over ``path`` only when
    complete, so a failure never leaves a partial file nor touches an existing one.

    Raises:
        ValueError: the suffix is neither ``.parquet`` nor ``.csv``.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in _SUFFIXES:
        raise ValueError(f"file {path}: unsupported file type {path.suffix!r}; expected .parquet or .csv")
    with atomic_output(path) as tmp:
        if suffix == ".csv":
            frame.to_csv(tmp, index=False, lineterminator="\n")
        else:
            frame.to_parquet(tmp, index=False)


# --- private helpers -----------------------------------------------------------------------------


def _read_csv(path: Path, name: str) -> pd.DataFrame:
    try:
        return pd.read_csv(
            path,
            usecols=lambda column: column in _KNOWN_SET,
            # Text columns stay text ("01" is a subject, not 1); an empty cell stays "" so it can be
            # told apart from a literal "nan" in the error message.
            dtype={column: str for column in STRING_COLUMNS},
            keep_default_na=False,
            encoding="utf-8-sig",
        )
    except pd.errors.EmptyDataError:
        raise DataFormatError("the file is empty", file=name) from None
    except (pd.errors.ParserError, UnicodeDecodeError) as err:
        raise DataFormatError(f"not a readable CSV file ({err})".replace("\n", " "), file=name) from None


def _read_parquet(path: Path, name: str) -> pd.DataFrame:
    try:
        names = pq.read_schema(path).names
        return pd.read_parquet(path, columns=[c for c in names if c in _KNOWN_SET])
    except (OSError, ValueError) as err:  # pyarrow's ArrowInvalid is a ValueError
        if isinstance(err, FileNotFoundError):
            raise
        raise DataFormatError(f"not a readable parquet file ({err})", file=name) from None


def _text_column(cells: pd.Series, name: str, column: str, first_row: int) -> pd.Series:
    text = cells.astype(str)
    missing = cells.isna().to_numpy() | (text.str.strip() == "").to_numpy()
    if missing.any():
        raise DataFormatError("missing value", file=name, column=column, row=_first(missing) + first_row)
    return text


def _numeric_column(cells: pd.Series, name: str, column: str, first_row: int) -> np.ndarray:
    if pd.api.types.is_bool_dtype(cells.dtype) or pd.api.types.is_numeric_dtype(cells.dtype):
        values = cells.to_numpy(dtype=np.float64, na_value=np.nan)
    else:
        values = pd.to_numeric(cells, errors="coerce").to_numpy(dtype=np.float64, na_value=np.nan)
    bad = ~np.isfinite(values)
    if bad.any():
        i = _first(bad)
        problem = _describe_bad_cell(cells.iloc[i])
        raise DataFormatError(problem, file=name, column=column, row=i + first_row)

    if column == schema.PHASE_IPSI:
        bad = (values < 0.0) | (values > 100.0)
        if bad.any():
            i = _first(bad)
            raise DataFormatError(
                f"phase must be within [0, 100], got {float(values[i])!r}",
                file=name,
                column=column,
                row=i + first_row,
            )
    if column == schema.STEP:
        bad = values != np.round(values)
        if bad.any():
            i = _first(bad)
            raise DataFormatError(
                f"step must be an integer, got {float(values[i])!r}",
                file=name,
                column=column,
                row=i + first_row,
            )
        return values.astype(np.int64)
    return values


def _describe_bad_cell(cell: object) -> str:
    """Say why ``cell`` did not convert to a finite float."""
    if cell is None or cell is pd.NA or (isinstance(cell, str) and not cell.strip()):
        return "missing value"
    try:
        value = float(cell)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return f"not a number: {cell!r}"
    if math.isnan(value):
        return "NaN is not allowed"
    return f"infinite value: {cell!r}" if isinstance(cell, str) else f"infinite value: {value!r}"


def _task_info_numbers(task_info: pd.Series, name: str, first_row: int) -> dict[str, np.ndarray]:
    """Parse each distinct ``task_info`` once; return its numeric keys as per-row columns."""
    codes, uniques = pd.factorize(task_info, sort=False)  # uniques in order of first appearance
    table = np.empty((len(uniques), len(_TASK_INFO_NUMBERS)), dtype=np.float64)
    for u, text in enumerate(uniques):
        try:
            table[u] = _task_info_row(str(text))
        except ValueError as err:
            row = int(np.argmax(codes == u)) + first_row
            raise DataFormatError(f"{err} in {text!r}", file=name, column=schema.TASK_INFO, row=row) from None
    return {key: table[codes, k] for k, key in enumerate(_TASK_INFO_NUMBERS)}


def _task_info_row(text: str) -> list[float]:
    info = parse_task_info(text)
    numbers = []
    for key in _TASK_INFO_NUMBERS:
        if key not in info:
            raise ValueError(f"no {key!r}")
        try:
            value = float(info[key])
        except ValueError:
            raise ValueError(f"{key!r} is not a number ({info[key]!r})") from None
        if not math.isfinite(value):
            raise ValueError(f"{key!r} is not finite ({info[key]!r})")
        numbers.append(value)
    return numbers


def _first(mask: np.ndarray) -> int:
    return int(np.argmax(mask))
