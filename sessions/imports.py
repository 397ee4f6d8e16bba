"""Import an uploaded log as a trial for review: gaitscope MCAP, the replay CSV, or a LocoHub table.

Validation comes first and is complete (the readers name file, row and column); only a file that
passes is turned into a recording, and only a finished recording gets database rows. Raw logs (CSV,
LocoHub, an MCAP without ``/gait_state``) are run through the estimators with default settings so
that every trial reviews the same way.
"""

from __future__ import annotations

import csv
import shutil
import time
from pathlib import Path

import numpy as np
import pandas as pd

from estimators.pipeline import TrainedModel
from sessions import schema
from sessions.errors import DataFormatError
from sessions.estimation import estimate
from sessions.locohub import read_table
from sessions.mcap_io import check_mcap, read_messages, read_sensor_frames
from sessions.recording import Recorder
from sessions.replay_io import read_replay_csv
from sessions.sources import frames_from_table
from sessions.store import Store

#: LocoHub columns a table needs to be replayed (heel positions are used when present).
LOCOHUB_REPLAY_COLUMNS = (
    schema.SUBJECT,
    schema.TASK_ID,
    schema.TIME_S,
    schema.FOOT_ANGLE,
    schema.SHANK_ANGLE,
)


def _csv_is_replay(path: Path) -> bool:
    with path.open(newline="", encoding="utf-8-sig", errors="replace") as f:
        header = next(csv.reader(f), [])
    names = {h.strip() for h in header}
    return schema.REPLAY_TIME in names and bool(names & set(schema.REPLAY_ANGLES))


def _locohub_frames(path: Path) -> list[schema.SensorFrame]:
    table = read_table(path, required=LOCOHUB_REPLAY_COLUMNS)
    parts, offset = [], 0.0
    for _, g in table.groupby([schema.SUBJECT, schema.TASK_ID], sort=False):
        g = g.sort_values(schema.TIME_S, kind="stable")
        g = g[np.concatenate([[True], np.diff(g[schema.TIME_S].to_numpy()) > 0])]
        t = g[schema.TIME_S].to_numpy(np.float64)
        part = pd.DataFrame(
            {
                schema.REPLAY_TIME: t - t[0] + offset,
                "foot_angle_deg": np.degrees(g[schema.FOOT_ANGLE].to_numpy(np.float64)),
                "shank_angle_deg": np.degrees(g[schema.SHANK_ANGLE].to_numpy(np.float64)),
            }
        )
        for col, name in ((schema.HEEL_FORWARD, "heel_forward_m"), (schema.HEEL_UP, "heel_up_m")):
            if col in g.columns:
                part[name] = g[col].to_numpy(np.float64)
        if schema.HEEL_STRIKE in g.columns:
            part[schema.REPLAY_HEEL_STRIKE] = g[schema.HEEL_STRIKE].to_numpy() > 0.5
        parts.append(part)
        dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.01
        offset = float(part[schema.REPLAY_TIME].iloc[-1]) + dt
    if not parts:
        raise DataFormatError("the table has no rows", file=str(path))
    return frames_from_table(pd.concat(parts, ignore_index=True))


def read_log(path: Path, filename: str) -> tuple[list[schema.SensorFrame], bool]:
    """Validate and read an uploaded file; returns its sensor frames and whether it holds gait states."""
    suffix = Path(filename).suffix.lower()
    name = filename
    if suffix == ".mcap":
        check_mcap(path, name=filename)
        frames = read_sensor_frames(path)
        has_states = next(iter(read_messages(path, ["/gait_state"])), None) is not None
    elif suffix == ".csv" and _csv_is_replay(path):
        data = read_replay_csv(path)
        table = pd.DataFrame({schema.REPLAY_TIME: data.time_s, **data.signals})
        if data.heel_strike is not None:
            table[schema.REPLAY_HEEL_STRIKE] = data.heel_strike
        frames, has_states = frames_from_table(table), False
    elif suffix in (".csv", ".parquet"):
        frames, has_states = _locohub_frames(path), False
    else:
        raise DataFormatError("unsupported file type (use .mcap, .csv or .parquet)", file=name)
    if len(frames) < 2:
        raise DataFormatError("the log holds fewer than 2 sensor frames", file=name)
    return frames, has_states


def import_log(
    path: Path, filename: str, subject: schema.Subject, store: Store, data_dir: Path, model: TrainedModel
) -> schema.Trial:
    """Turn a validated upload into a review session with one trial; nothing is stored on failure."""
    frames, has_states = read_log(path, filename)
    rel = f"recordings/upload_{int(time.time() * 1000)}_{Path(filename).stem[:40]}.mcap"
    target = data_dir / rel
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        if has_states:
            shutil.copyfile(path, target)
            samples = sum(1 for _ in read_messages(target, ["/gait_state"]))
            duration = frames[-1].t - frames[0].t
        else:
            settings = schema.SessionSettings()
            states = estimate(frames, model, subject.leg_length_m, subject.mass_kg, settings)
            with Recorder(target, time.time_ns(), {"subject": subject.code, "source": f"upload {filename}"}) as rec:
                rec.write("/settings", 0.0, settings)
                for f, s in zip(frames, states, strict=True):
                    rec.write("/sensor", s.t, f)
                    rec.write("/gait_state", s.t, s)
                    rec.write("/torque", s.t, schema.TorqueCommand(seq=s.seq, t=s.t, torque_Nm=s.torque_Nm))
            samples, duration = len(states), states[-1].t - states[0].t
        session = store.create_session(
            schema.SessionCreate(subject_id=subject.id, source=schema.UploadSource(filename=filename), start=False)
        )
        store.set_session_state(session.id, "stopped")
        trial = store.create_trial(session.id, filename, rel, status="uploaded")
        return store.finish_trial(trial.id, "uploaded", samples, duration)
    except BaseException:
        target.unlink(missing_ok=True)
        raise
