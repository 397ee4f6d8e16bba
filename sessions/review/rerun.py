"""Reviewing a recorded trial: re-run its raw sensor frames through the estimators.

Two modes (:class:`~gaitscope.sessions.schema.RerunRequest`):

* **as recorded** (``settings=None``, the default): the trial's ``/settings`` timeline is replayed, the
  settings in force at its first frame and then each recorded change from the frame after the one it
  followed, as it applied live. The result reproduces the recorded ``/gait_state`` to floating-point
  round-off: the baseline ("what ran") a clinician compares a what-if with.
* **what if** (``settings`` given): those settings, model included, held constant over the whole trial.

Which estimators (:mod:`gaitscope.sessions.registry`): ``estimators`` when given (any subset of the registered ones
whose channels the trial has), else the trial's recorded stack (``ESTIMATORS_KEY`` in its metadata; a
recording made before stacks had one ran the phase EKF and its timing-based estimate), else every
estimator the trial's channels allow (:func:`rerun_choices` says which can run, for a review's picker).
Each one's outputs come back as ``<name>.<output>`` columns beside the gait state's, so the review
overlays them. The primary is the settings' when the subset has it, else its first estimator with a
phase; a recorded switch to one the subset lacks is not applied.

The estimator is built as the live one was (:class:`~gaitscope.sessions.live.runtime.SessionRuntime`): the model named
in the settings, the subject's leg length and mass, the sample period in the recording's metadata record
(:data:`~gaitscope.sessions.formats.recording.SAMPLE_PERIOD_KEY`) and the recording's session clock, so the states come
out on the times of the recorded ones and overlay them; its torque passes the live loop's last guard
(:func:`~gaitscope.sessions.live.runtime.safe_torque`). In both modes the IMU mounting calibration the recording
holds (its ``/imu_calibration`` messages: the one in force at the trial's start, and one made during it)
is applied to the IMU front ends from where it was recorded, as it was live; and the GP-EKF (``gp_ekf``) does
not retrain: it installs the model versions the recording holds (``/gp_models``) at the heel strikes where
they were installed live (:class:`~gaitscope.sessions.gp_models.GPReplay`), so its outputs are those that ran.

Where the estimators start. A recording keeps the whole estimation state at its trial's start (its
``/estimation_state`` message, :mod:`~gaitscope.sessions.formats.stack_state`: every filter, the stack's primary,
blend and ramps, the torque gain's ramps, the IMU front ends, the GP-EKF's models, the fingerprint). A re-run as
recorded of the recorded stack restores it and steps the trial's frames from there, so every trial, the first of
its session or a later one, is reproduced bit for bit from its first frame (``==``, torque and gait state). A
what-if, or a re-run of other estimators, starts from fresh filters at the trial's first frame; so does a
recording without the state (made before gaitscope kept it, or by another tool) or with one that is damaged or
refused: then a trial that began mid-session can differ from what ran over its first strides, until the filters
converge. The answer says which (its ``start`` entry, :func:`rerun_series`).

Frames are read lazily and the result is decimated on the fly (:class:`~sessions.formats.mcap_io.SeriesBuilder`),
so a re-run of an hour-long trial needs memory for ``max_points`` rows, not for the hour. The estimators always
start at the trial's first frame; only the states inside ``[t0, t1]`` are returned.
"""

from __future__ import annotations

import itertools
import math
import struct
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Final

from mcap.exceptions import McapError
from mcap.reader import make_reader

from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.estimation import DEFAULT_PERIOD, FrameEstimator
from gaitscope.sessions.formats import stack_state
from gaitscope.sessions.formats.mcap_io import (
    SeriesBuilder,
    count_messages,
    iter_sensor_frames,
    metadata_of,
    read_messages,
    series_window,
)
from gaitscope.sessions.formats.recording import ESTIMATORS_KEY, FINGERPRINT_KEY, METADATA_NAME, SAMPLE_PERIOD_KEY
from gaitscope.sessions.gp_models import GPReplay, gp_ekf_of
from gaitscope.sessions.imu_calibration import apply_calibration
from gaitscope.sessions.live.runtime import safe_torque
from gaitscope.sessions.personalization.intent_model import INTENT_MODEL_KEY, from_metadata
from gaitscope.sessions.registry import OPT_IN, channels_of, feeds, redundant
from gaitscope.sessions.schema import GPModelRecord, ImuCalibration, RerunChoices, SensorFrame, SessionSettings

__all__ = [
    "FRESH",
    "IMPORTED",
    "NOT_RECORDED",
    "REFUSED",
    "RESUMED",
    "START_KEY",
    "TORQUE_DIFF_KEY",
    "recorded_settings",
    "recorded_stack",
    "rerun_choices",
    "rerun_series",
    "trial_channels",
]

#: What ran before the stack was recorded: the phase EKF (with its detector) and the timing-based estimate.
_BEFORE_STACKS: Final = ("phase_ekf", "tbe")

#: Frames read to learn a trial's channels.
_PROBE: Final = 200
#: The ``start`` of a re-run's answer: how its estimators began (see the module docstring).
RESUMED: Final = (
    "Resumed from the estimation state recorded at the trial's start: the re-run reproduces what ran from the "
    "first frame."
)
FRESH: Final = (
    "Started from fresh filters at the trial's first frame (a what-if, or other estimators than those that ran): "
    "where the trial began mid-session, its first strides differ from what ran until the filters converge."
)
NOT_RECORDED: Final = (
    "This recording holds no estimation state from the trial's start (made before gaitscope kept one, or by "
    "another tool): the re-run starts from fresh filters, so its first strides may differ from what ran."
)
IMPORTED: Final = (
    "An imported log: its states were estimated from its first frame with fresh filters, and so is the re-run."
)
REFUSED: Final = (
    "The estimation state recorded at the trial's start could not be restored ({why}): the re-run starts from "
    "fresh filters, so its first strides may differ from what ran."
)
#: The metadata ``source`` of a log estimated at its upload (:mod:`gaitscope.sessions.formats.imports`).
_IMPORT_SOURCE: Final = "upload "
#: Keys of a re-run's answer that are not series: how it started, and how far its torque is from the recording's.
START_KEY: Final = "start"
TORQUE_DIFF_KEY: Final = "recorded_torque_diff_Nm"
_NO_SETTINGS: Final = (
    "the settings in force at the trial's first frame are not recorded (no /settings message before it), "
    "so what ran cannot be reproduced; re-run it with chosen settings ('what if')"
)


def recorded_settings(path: Path) -> SessionSettings:
    """The settings in force at the trial's first frame (its first ``/settings`` message).

    Raises:
        DataFormatError: the file records none, or a bad one.
    """
    for _, log_time, msg in read_messages(path, ["/settings"]):
        return _settings(path, log_time, msg)
    raise DataFormatError(_NO_SETTINGS, file=str(path))


def rerun_series(
    path: Path,
    models: Callable[[str], TrainedModel],
    leg_length: float,
    mass_kg: float,
    settings: SessionSettings | None = None,
    t0: float | None = None,
    t1: float | None = None,
    max_points: int = 2000,
    estimators: Sequence[str] | None = None,
    fingerprint: Sequence[float] | None = None,
) -> dict[str, list[Any]]:
    """Series (as :func:`~gaitscope.sessions.formats.mcap_io.read_series`) of the trial re-estimated, and the
    outputs of each estimator as ``<name>.<output>`` columns (None where it had failed); and two entries that
    are not series: ``start`` (:data:`START_KEY`), one sentence saying how the estimators began (:data:`RESUMED`,
    :data:`FRESH`, :data:`IMPORTED`, :data:`NOT_RECORDED`, :data:`REFUSED`), and ``recorded_torque_diff_Nm``
    (:data:`TORQUE_DIFF_KEY`), the largest ``|torque - recorded torque|`` (N m) over the samples returned, each
    against the recorded gait state of the same frame, before decimation (None: the trial records none).

    Args:
        path: the trial's MCAP file.
        models: the trained model of a name (the settings name the model).
        leg_length, mass_kg: the subject's (m, kg).
        settings: None to replay the recorded settings (as recorded); else held over the whole trial
            (what if).
        t0, t1: session times (s) of the states returned (None: unbounded).
        max_points: decimation bound, as :func:`~gaitscope.sessions.formats.mcap_io.read_series`.
        estimators: the estimators to run (None: the recorded stack; see the module docstring).
        fingerprint: the subject's gait fingerprint, which the personalized filter ``fp_ls`` runs.

    Raises:
        DataFormatError: a bad file; as recorded, a file without the settings of its first frame, or
            whose recorded model changes mid-trial; an unknown estimator, or one whose channels the
            trial lacks.
    """
    window = series_window(path, t0, t1)
    if window is None:
        return _answer(SeriesBuilder(0, max_points), FRESH, None)
    lo, hi = window
    n = count_messages(path, "/sensor", lo, hi)
    builder: SeriesBuilder | None = None
    names: Sequence[str] | None = estimators
    if names is None and settings is not None:
        names = settings.estimators
    ran = names is None and (names := recorded_stack(path)) is not None
    # the channels are checked unless the stack is the recorded one (it ran: on a device, whatever came)
    channels = None if ran else trial_channels(path)
    resumable = settings is None and names is not None and _ran_as_recorded(path, tuple(names), fingerprint)
    start = FRESH
    current = settings
    estimator: FrameEstimator | None = None
    topics = ["/sensor", "/imu_calibration", "/gait_state"]
    topics += ["/settings"] if settings is None else []
    imu: ImuCalibration | None = None  # the IMU calibration the recording holds, applied as it was live
    # the estimation state at the trial's start (written when its encoding was back: read first)
    recorded_state = next((m for _, _, m in read_messages(path, [stack_state.TOPIC])), None) if resumable else None
    gp = _gp_replay(path)  # the GP-EKF's installs, each recorded after its heel strike: all read first
    gp_ekf = None
    stepped: tuple[int, float] | None = None  # the last frame re-run (log time) and its torque, while returned
    worst: float | None = None  # the largest |torque - recorded torque| so far
    # Log-time order, equal times in file order: the order they were written in, so a /settings
    # message applies to the frames written after it, exactly as the change applied live.
    for topic, log_time, msg in read_messages(path, topics):
        if hi is not None and log_time > hi:
            break
        if topic == "/gait_state":  # recorded after its frame, at its log time
            recorded_torque = _recorded_torque(msg)
            if stepped is not None and stepped[0] == log_time and recorded_torque is not None:
                diff = abs(stepped[1] - recorded_torque)
                worst = diff if worst is None or not diff <= worst else worst
            stepped = None
            continue
        if topic == "/settings":
            recorded = _settings(path, log_time, msg)
            if current is not None and recorded.model != current.model:
                raise DataFormatError(
                    f"the recorded model changes from {current.model!r} to {recorded.model!r} at {log_time} ns",
                    file=str(path),
                )
            if estimator is not None and recorded != current:
                _retune(estimator, recorded)
            current = recorded
            continue
        if topic == "/imu_calibration":
            imu = _imu_calibration(path, log_time, msg)
            if estimator is not None:
                apply_calibration(estimator.stack, imu)
            continue
        frame = _frame(path, log_time, msg)
        if current is None:
            raise DataFormatError(_NO_SETTINGS, file=str(path))
        if estimator is None:
            origin = _time_origin(path, frame)
            model = models(current.model)
            if resumable:
                assert names is not None
                estimator, start = _resumed(recorded_state, model, tuple(names), origin)
                if recorded_state is None and _metadata(path).get("source", "").startswith(_IMPORT_SOURCE):
                    start = IMPORTED  # estimated at the upload from its first frame: fresh filters are what ran
            if estimator is not None:  # the state holds the settings, IMU calibration and GP models of the start
                if estimator.settings != current:
                    _retune(estimator, current)
                gp.installs = [i for i in gp.installs if i[0] > -math.inf]
            else:
                # The frames are on the session clock already (resynchronised live if need be): never again.
                period = _sample_period(path, frame)
                try:
                    estimator = FrameEstimator(
                        model,
                        leg_length,
                        mass_kg,
                        current,
                        period,
                        origin,
                        max_jump_s=math.inf,
                        estimators=names,
                        channels=channels,
                        fingerprint=fingerprint,
                        intent=from_metadata(_metadata(path).get(INTENT_MODEL_KEY), str(path)),  # what ran
                    )
                except ValueError as exc:  # unknown estimators, missing channels, no fingerprint
                    raise DataFormatError(str(exc), file=str(path)) from exc
                if imu is not None:
                    apply_calibration(estimator.stack, imu)
            stack = estimator.stack
            gp_ekf = gp_ekf_of(stack) if gp.active else None
            columns = [f"{name}.{o}" for name, outs in zip(stack.names, stack.outputs, strict=True) for o in outs]
            builder = SeriesBuilder(n, max_points, columns)
        admission = estimator.admit(frame)
        if admission.verdict == "order":
            continue  # reordered or repeated, skipped as live (not in gaitscope's own recordings)
        if gp_ekf is not None:
            gp.before(gp_ekf, admission.t, estimator.sample_period)
        state = estimator.step(frame, 0)
        torque = safe_torque(state.torque_Nm, current.max_torque_Nm)  # the live loop's last guard, as live
        if torque != state.torque_Nm:
            state = state.model_copy(update={"torque_Nm": torque, "fault": True})
        if lo is None or log_time >= lo:
            assert builder is not None
            stepped = (log_time, state.torque_Nm)
            row = state.model_dump()
            last = estimator.last
            if last is not None:
                for name, outs, y in zip(estimator.stack.names, estimator.stack.outputs, last.outputs, strict=True):
                    for i, o in enumerate(outs):
                        row[f"{name}.{o}"] = None if y is None else float(y[i])
            builder.add(row)
    if estimator is None:  # no frame: nothing ran, nothing to say about how it began
        start = FRESH
    return _answer(builder or SeriesBuilder(0, max_points), start, worst)


def _answer(builder: SeriesBuilder, start: str, worst: float | None) -> dict[str, list[Any]]:
    """The series, with how the estimators began and the largest torque difference (:func:`rerun_series`)."""
    return {**builder.result(), START_KEY: [start], TORQUE_DIFF_KEY: [worst]}


def _ran_as_recorded(path: Path, names: tuple[str, ...], fingerprint: Sequence[float] | None) -> bool:
    """Whether a re-run as recorded of ``names`` with ``fingerprint`` runs what ran: the recorded stack, and
    (when its personalized filter ran) the recorded fingerprint."""
    if names != recorded_stack(path):
        return False
    recorded = recorded_fingerprint(path)
    return fingerprint is None or recorded is None or [float(x) for x in fingerprint] == recorded


def _resumed(
    recorded: object, model: TrainedModel, names: tuple[str, ...], origin: float | None
) -> tuple[FrameEstimator | None, str]:
    """The estimator restored from the recorded state (None: none, or refused) and what the answer says of it."""
    if recorded is None:
        return None, NOT_RECORDED
    try:
        estimator = stack_state.restore(recorded, model, names)
    except stack_state.StateRefused as exc:
        return None, REFUSED.format(why=str(exc))
    estimator.replaying(origin)
    return estimator, RESUMED


def _retune(estimator: FrameEstimator, settings: SessionSettings) -> None:
    try:
        estimator.retune(settings)
    except ValueError:
        pass  # a switch to a primary this re-run does not have: the others apply


def _recorded_torque(msg: object) -> float | None:
    """A recorded gait state's torque (None: it has none to compare with)."""
    torque = msg.get("torque_Nm") if isinstance(msg, dict) else None
    return float(torque) if isinstance(torque, int | float) and not isinstance(torque, bool) else None


def rerun_choices(path: Path, fingerprint: Sequence[float] | None = None) -> RerunChoices:
    """Which estimators :func:`rerun_series` can run on the trial: its recorded stack (they ran, whatever
    the channels), and every registered estimator its first frames' channels can feed, as
    :func:`~gaitscope.sessions.registry.feeds` reckons it; the personalized fingerprint filter (``fp_ls``) only with
    the subject's ``fingerprint``.

    Raises:
        DataFormatError: a bad file.
    """
    recorded = recorded_stack(path)
    sent = trial_channels(path)
    fed = feeds(sent)
    ran = set(recorded or ())
    runnable = [n for n, f in fed.items() if (n in ran or not f.missing) and (n != "fp_ls" or fingerprint is not None)]
    if recorded is not None:
        default = list(recorded)
    else:  # as resolve(None, channels) runs them: the opt-in ones left out, and those fed by them
        default = [n for n in runnable if n not in OPT_IN and not redundant(n, sent)]
        default = [n for n in default if all(set(by) & set(default) for by in fed[n].derived.values())]
    return RerunChoices(
        recorded=None if recorded is None else list(recorded),
        default=default,
        runnable=runnable,
        derived={n: {c: list(by) for c, by in fed[n].derived.items()} for n in runnable if fed[n].derived},
        refused={
            n: f"the trial does not send {', '.join(f.missing)}" if f.missing else _NO_FINGERPRINT
            for n, f in fed.items()
            if n not in runnable
        },
    )


_NO_FINGERPRINT = "needs the subject's calibrated gait fingerprint"


def recorded_fingerprint(path: Path) -> list[float] | None:
    """The fingerprint the trial's personalized filter ran with (its metadata), None when none ran."""
    text = _metadata(path).get(FINGERPRINT_KEY)
    if not text:
        return None
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        raise DataFormatError(f"bad recorded fingerprint {text[:80]!r}", file=str(path)) from None
    if not all(math.isfinite(v) for v in values):
        raise DataFormatError("the recorded fingerprint is not finite", file=str(path))
    return values


def recorded_stack(path: Path) -> tuple[str, ...] | None:
    """The estimator stack a trial was recorded with (its metadata), ``("phase_ekf", "tbe")`` for a
    gaitscope recording made before stacks were recorded, None for another tool's log."""
    meta = _metadata(path)
    text = meta.get(ESTIMATORS_KEY)
    if text is not None:
        return tuple(n for n in text.split(",") if n)
    return _BEFORE_STACKS if SAMPLE_PERIOD_KEY in meta else None


def trial_channels(path: Path) -> set[str]:
    """The channels the trial's first :data:`_PROBE` frames send (:func:`~gaitscope.sessions.registry.channels_of`)."""
    return channels_of(f for _, f in itertools.islice(iter_sensor_frames(path), _PROBE))


def _settings(path: Path, log_time: int, msg: object) -> SessionSettings:
    try:
        return SessionSettings.model_validate(msg)
    except ValueError as exc:
        raise DataFormatError(f"bad /settings message at {log_time} ns: {exc}", file=str(path)) from exc


def _gp_replay(path: Path) -> GPReplay:
    """The recording's ``/gp_models`` records, ready to replay."""
    replay = GPReplay()
    for _, log_time, msg in read_messages(path, ["/gp_models"]):
        try:
            replay.add(GPModelRecord.model_validate(msg))
        except ValueError as exc:
            raise DataFormatError(f"bad /gp_models message at {log_time} ns: {exc}", file=str(path)) from exc
    return replay


def _imu_calibration(path: Path, log_time: int, msg: object) -> ImuCalibration:
    try:
        return ImuCalibration.model_validate(msg)
    except ValueError as exc:
        raise DataFormatError(f"bad /imu_calibration message at {log_time} ns: {exc}", file=str(path)) from exc


def _frame(path: Path, log_time: int, msg: object) -> SensorFrame:
    try:
        return SensorFrame.model_validate(msg)
    except ValueError as exc:
        raise DataFormatError(f"bad /sensor frame at {log_time} ns: {exc}", file=str(path)) from exc


def _time_origin(path: Path, first: SensorFrame) -> float | None:
    """``time_origin`` that puts the frames on the recording's session clock: the first frame's ``t``
    minus that of the first gait state (0 for a live recording, whose frames carry session time; the
    log's own first time for an import, whose frames keep it). None (start at 0) without gait states."""
    for _, log_time, msg in read_messages(path, ["/gait_state"]):
        t = msg.get("t") if isinstance(msg, dict) else None
        if not isinstance(t, int | float):
            raise DataFormatError(f"/gait_state message without t at {log_time} ns", file=str(path))
        return first.t - t
    return None


def _sample_period(path: Path, first: SensorFrame) -> float:
    """The sample period (s) the recorded states were estimated with.

    Read from the metadata record. Recordings made before it was recorded get what made them: the live
    runtime built a device's or a replay's estimator before it knew their rate (so with
    ``DEFAULT_PERIOD``); a simulated source's was ``1 / rate``, and an import's
    (:func:`~gaitscope.sessions.estimation.estimate`) the mean frame period, which equals it to round-off.
    """
    meta = _metadata(path)
    text = meta.get(SAMPLE_PERIOD_KEY)
    if text is not None:
        try:
            period = float(text)
        except ValueError:
            period = math.nan
        if not (math.isfinite(period) and period > 0):
            raise DataFormatError(f"bad {SAMPLE_PERIOD_KEY} {text!r} in the metadata record", file=str(path))
        return period
    if meta.get("source") in ("device", "replay"):
        return DEFAULT_PERIOD
    n = count_messages(path, "/sensor", None, None)
    last = _last_frame(path)
    if n > 1 and last is not None and last.t > first.t:
        return (last.t - first.t) / (n - 1)
    return DEFAULT_PERIOD


def _metadata(path: Path) -> dict[str, str]:
    """Key/values of the recording's ``gaitscope`` metadata record (empty without one)."""
    return metadata_of(path, METADATA_NAME)


def _last_frame(path: Path) -> SensorFrame | None:
    """The last ``/sensor`` frame (read through the index: one chunk)."""
    try:
        with open(path, "rb") as f:
            for _, _, message in make_reader(f).iter_messages(topics=["/sensor"], reverse=True):
                return SensorFrame.model_validate_json(message.data)
    except (McapError, ValueError, struct.error, EOFError) as exc:
        raise DataFormatError(f"damaged /sensor data ({exc})", file=str(path)) from exc
    return None
