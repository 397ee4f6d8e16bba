"""A session's estimates as one CSV table: one row per gait state of every readable trial, in order.

The first line names the columns (:data:`CSV_COLUMNS`); times are session times (s); phases are in % of the
gait cycle (0 at heel strike, as the dashboard shows them: ``phase_percent``); flags are 0 or 1; a missing value
is an empty cell.
"""

from __future__ import annotations

import csv
from collections.abc import Callable
from pathlib import Path
from typing import Final

from gaitscope.sessions import schema
from gaitscope.sessions.formats.mcap_io import count_messages, read_messages

__all__ = ["CSV_COLUMNS", "write_estimates_csv"]

_STATE: Final = (
    "t", "phase", "phase_rate", "stride_length_m", "incline_deg", "torque_Nm", "heel_strike", "fault",
    "backup_reset", "thigh_angle_deg", "shank_angle_deg", "foot_angle_deg", "tbe_phase",
)  # fmt: skip
#: Gait-state fields written in % (of the cycle, 0-1 in the recording), and their columns' names.
_PERCENT: Final = {"phase": "phase_percent", "tbe_phase": "tbe_phase_percent"}
CSV_COLUMNS: Final = ("trial_id", "trial_name", *(_PERCENT.get(c, c) for c in _STATE))
_BOOL: Final = frozenset(("heel_strike", "fault", "backup_reset"))
_PROGRESS_EVERY: Final = 2000


def _cell(name: str, v: object) -> str:
    if v is None:
        return ""
    if name in _BOOL:
        return "1" if v else "0"
    if name in _PERCENT and isinstance(v, int | float):
        return repr(round(100.0 * float(v), 9))  # no 12.300000000000001 from the scaling
    return repr(float(v)) if isinstance(v, int | float) else str(v)


def write_estimates_csv(
    trials: list[tuple[schema.Trial, Path]], out: Path, on_progress: Callable[[float], None] | None = None
) -> int:
    """Write the trials' gait states to ``out``; the number of rows written (the header not counted).

    ``on_progress(fraction)`` is called every few thousand rows.
    """
    total = sum(count_messages(path, "/gait_state", None, None) for _, path in trials) or 1
    rows = 0
    with out.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(CSV_COLUMNS)
        for trial, path in trials:
            for _, _, msg in read_messages(path, ["/gait_state"]):
                w.writerow([trial.id, trial.name, *(_cell(c, msg.get(c)) for c in _STATE)])
                rows += 1
                if on_progress is not None and rows % _PROGRESS_EVERY == 0:
                    on_progress(min(1.0, rows / total))
    return rows
