"""Sensor frames in, gait states out: the session's estimator stack as a device stream needs it.

The one sensor-to-estimate path: used live by :class:`~gaitscope.sessions.live.runtime.SessionRuntime`, and offline
to re-run recordings (:mod:`gaitscope.sessions.review.rerun`) and to import raw logs (:func:`estimate`). The
estimators and the torque are :class:`~gaitscope.sessions.stack.EstimatorStack`'s; this module adds what a device
stream needs around it (session time, derived velocities, soft start).
"""

from __future__ import annotations

import json
import math
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from typing import Final, Literal

import numpy as np

from gaitscope.estimators.intent import BKFConfig
from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.estimators.protocol import (
    ANGLE_CHANNELS,
    HEEL_STRIKE,
    MAX_GAP_S,
    SENSOR_CHANNELS,
    Estimator,
    input_names,
)
from gaitscope.sessions import schema
from gaitscope.sessions.intent_boost import IntentBoost
from gaitscope.sessions.registry import StackContext, build_stack, channels_of
from gaitscope.sessions.schema import GaitState, SensorFrame, SessionSettings
from gaitscope.sessions.stack import EstimatorStack, StackSample
from gaitscope.sessions.torque_gain import TorqueGain

#: Assumed sample period until the source's rate is known (s).
DEFAULT_PERIOD = 0.005
#: A device clock that goes back by less than this is a reordered frame (dropped); by more, a restart.
REORDER_WINDOW_S = 0.5
#: A device clock that jumps ahead by more than this in one frame is resynchronised.
MAX_JUMP_S = 2.0


class FrameRefused(ValueError):
    """A frame the estimator did not take (its time does not follow the last one); nothing changed."""


@dataclass(frozen=True)
class Admission:
    """Where a frame goes in session time, decided before anything changes.

    ``verdict``: ``ok``; ``resync`` (the device clock restarted or jumped: session time continues one
    sample period after the last one); ``order`` (a reordered or repeated frame: refused).
    """

    verdict: Literal["ok", "resync", "order"]
    t: float
    reason: str = ""


class FrameEstimator:
    """Sensor frames in, gait states out: the estimator stack plus what a device stream needs around it.

    Session time starts at 0 on the first frame (or is ``frame.t - time_origin`` when given) and always
    increases: a device whose clock restarts (a reboot) or jumps by more than ``max_jump_s`` is
    resynchronised, and :meth:`resync` moves session time to a wall clock's (a reconnect after a
    pause). Angular velocities a device does not send are derived by backward difference.

    The stack (:mod:`gaitscope.sessions.registry`, :mod:`gaitscope.sessions.stack`) is ``estimators`` (names), else the
    settings' ``estimators``, else every estimator the source's ``channels`` allow (all of them when the
    channels are unknown), plus ``extra`` instances; its primary is the settings' ``primary``. The gait
    state is the primary's outputs and the stack's torque (``foot_pred_deg`` and ``shank_pred_deg``: the
    gait model at the prior estimate).

    Soft start (``soft_start``): the torque gain and bound ramp from 0 to the session's values at the
    rate limits of :data:`~gaitscope.sessions.schema.SETTING_LIMITS` (0.5 gain/s, 10 N m/s), from the first frame
    and again after every restart or reset of the primary, so that assistance never starts as a step.
    The intent boost (:mod:`gaitscope.sessions.intent_boost`) stays within the same ramp: the effective gain
    ``gain x (1 + boost)`` never exceeds the ramp's ``0.5 gain/s x time since it started``, nor the
    torque the ramped bound. Deterministic in session time, so a re-run reproduces it. The set gain, the
    ramp and the boost have one owner, :attr:`gain` (:class:`~gaitscope.sessions.torque_gain.TorqueGain`).

    Attributes:
        stack: the estimators and the torque.
        last: what the stack made of the last frame (every estimator's outputs).
        last_t: session time of the last frame stepped.
        notes: what happened that deserves an event (resynchronisations, filter faults); the caller
            drains it after each step (and may merge them).
        events: estimator failures and primary switches; the caller logs each one.
        implausible: channel values treated as missing (outside ``SENSOR_LIMITS``) since the start.
        faults: samples whose state has ``fault`` set.

    Raises:
        ValueError: unknown estimators, or a primary the stack cannot run.
        gaitscope.sessions.registry.MissingChannels: an estimator asked for whose required channels the source lacks.
    """

    def __init__(
        self,
        model: TrainedModel,
        leg_length: float,
        mass_kg: float,
        settings: SessionSettings,
        sample_period: float = DEFAULT_PERIOD,
        time_origin: float | None = None,
        *,
        soft_start: bool = True,
        max_jump_s: float = MAX_JUMP_S,
        reorder_window_s: float = REORDER_WINDOW_S,
        estimators: Sequence[str] | None = None,
        channels: Collection[str] | None = None,
        extra: Sequence[Estimator] = (),
        blend_s: float = schema.PRIMARY_BLEND_S,
        fingerprint: Sequence[float] | None = None,
        intent: BKFConfig | None = None,
    ):
        if not (math.isfinite(sample_period) and 1e-5 <= sample_period <= 1.0):
            sample_period = DEFAULT_PERIOD
        self.sample_period = sample_period
        self.stack: EstimatorStack = build_stack(
            StackContext(
                model, leg_length, mass_kg, sample_period, None if fingerprint is None else tuple(fingerprint), intent
            ),
            names=settings.estimators if estimators is None else estimators,
            channels=channels,
            primary=settings.primary,
            torque_gain=settings.torque_gain,
            max_torque=settings.max_torque_Nm,
            blend_s=blend_s,
            extra=extra,
        )
        self._topics = list(schema.estimator_channels(self.stack.names))
        # channels an estimator of the stack reads beyond those every frame's step fills (below)
        read = dict.fromkeys(c for est in self.stack.estimators for c in input_names(est))
        #: the channels each frame's step reads, by their names in the channel table
        self._read: tuple[str, ...] = (*_STEPPED, *(c for c in read if c not in _STEPPED and c in schema.CHANNELS))
        self._json_templates = [
            _outputs_templates(name, outs) for name, outs in zip(self.stack.names, self.stack.outputs, strict=True)
        ]
        self.settings = settings
        #: the one owner of the effective torque gain: the set gain, the soft start's ramp, the intent boost
        self.gain = TorqueGain(self.stack, settings, soft_start)
        self.max_jump_s = max_jump_s
        self.reorder_window_s = reorder_window_s
        self.last: StackSample | None = None
        self.last_t = 0.0
        self.notes: list[str] = []
        self.events: list[str] = []
        self.implausible = 0
        self.faults = 0
        self._t_offset = time_origin
        #: The last frame stepped: its session time and foot and shank angles (None: none yet).
        self._prev: tuple[float, float | None, float | None, float | None] | None = None
        self._standing = False
        #: when and why the primary last lost track (:mod:`gaitscope.estimators.lock`); None: never
        self.last_lost: tuple[float, str] | None = None
        self._min_next_t = -math.inf
        self._last_recv_ns = 0
        self.retune(settings)

    @property
    def primary(self) -> str | None:
        """The estimator driving the torque now (the settings' unless it failed; None: none)."""
        return self.stack.primary

    @property
    def soft_start(self) -> bool:
        """Whether assistance ramps up (:attr:`gain` owns the ramp)."""
        return self.gain.soft_start

    @property
    def intent_boost(self) -> IntentBoost:
        """Assistance follows intent (the ``intent_gain_boost`` setting; off by default; :attr:`gain` applies it)."""
        return self.gain.boost

    def retune(self, s: SessionSettings) -> None:
        """Take new settings from the next frame on (the soft start, if running, still caps the torque).

        Raises:
            ValueError: ``s.primary`` cannot drive the torque (not in the stack, no phase, failed); the
                other settings are applied.
        """
        self.settings = s
        self.gain.set(s, self.last_t)
        self.stack.retune(measurement_noise_scale=s.measurement_noise_scale, process_noise_scale=s.process_noise_scale)
        self.events.extend(self.stack.take_events())
        if s.primary != self.stack.requested:
            self.stack.set_primary(s.primary)

    def recorded_channels(self) -> dict[str, tuple[str, type[schema.BaseModel]]]:
        """The MCAP channels of the stack's outputs, for :class:`~gaitscope.sessions.formats.recording.Recorder`."""
        return schema.estimator_channels(self.stack.names)

    def output_json(self, seq: int) -> list[tuple[str, bytes]]:
        """The last frame's outputs, recorded as they are made: ``(topic, JSON of an``
        :class:`~gaitscope.sessions.schema.EstimatorOutputs` ``)`` per estimator, values null once it failed.

        Built as text rather than through the model: per sample and estimator, building and dumping the
        model cost more than the rest of the recording (``tests/sessions/test_stack.py`` checks that it
        reads back as the model).
        """
        last = self.last
        if last is None:
            return []
        seq, t = int(seq), float(self.last_t)
        out = []
        for topic, (ok, failed), y in zip(self._topics, self._json_templates, last.outputs, strict=True):
            # %r of a float is its shortest round-trip repr: valid JSON for the finite values the stack lets by
            out.append((topic, (failed % (seq, t) if y is None else ok % (seq, t, *y.tolist())).encode()))
        return out

    def recorded_json(self, frame: SensorFrame, state: GaitState, command: bytes) -> list[tuple[str, bytes]]:
        """What is recorded of the last sample, as ``(topic, JSON)`` for
        :meth:`~gaitscope.sessions.formats.recording.Recorder.write_json`: every estimator's outputs
        (:meth:`output_json`), the sensor frame at session time (:func:`frame_json`), the gait state and
        ``command``, the JSON of the torque command the device got (:func:`torque_json`)."""
        out = self.output_json(state.seq)
        out += (
            ("/sensor", frame_json(frame, state.t)),
            ("/gait_state", state.model_dump_json().encode()),
            ("/torque", command),
        )
        return out

    def resync(self, elapsed_s: float) -> None:
        """The device reconnected ``elapsed_s`` seconds (wall clock) into the session: its next frame
        starts a new clock mapping at session time ``max(last_t + period, elapsed_s)``."""
        if self._prev is None:
            return
        self._t_offset = None
        self._min_next_t = max(self.last_t + self.sample_period, elapsed_s if math.isfinite(elapsed_s) else 0.0)

    def admit(self, frame: SensorFrame, recv_ns: int = 0) -> Admission:
        """Where ``frame`` would go; changes nothing.

        ``recv_ns`` (the server's wall clock at arrival, 0 when unknown) tells a real pause of the
        device from a glitch of its clock: on a resynchronisation session time advances by the wall
        time since the last frame (at least one sample period).
        """
        if self._prev is None:
            origin = frame.t if self._t_offset is None else self._t_offset
            return Admission("ok", frame.t - origin)
        next_t = self.last_t + self.sample_period
        if recv_ns and self._last_recv_ns and recv_ns > self._last_recv_ns:
            next_t = max(next_t, self.last_t + (recv_ns - self._last_recv_ns) / 1e9)
        if self._t_offset is None:  # after resync(): a new clock mapping
            return Admission("resync", max(next_t, self._min_next_t), "the device reconnected")
        t = frame.t - self._t_offset
        if not math.isfinite(t):
            return Admission("resync", next_t, f"device time {frame.t:g} s cannot be placed")
        if t > self.last_t:
            if t - self.last_t <= self.max_jump_s or abs(t - next_t) <= 0.5:
                return Admission("ok", t)
            return Admission("resync", next_t, f"device clock jumped ahead by {t - self.last_t:.3g} s")
        if self.last_t - t <= self.reorder_window_s:
            return Admission("order", t, f"frame seq {frame.seq}: time {frame.t:g} does not follow the last frame")
        return Admission("resync", next_t, f"device clock went back by {self.last_t - t:.3g} s (a restart?)")

    def accepts(self, frame: SensorFrame) -> bool:
        """True unless ``frame`` would be refused as reordered or repeated."""
        return self.admit(frame).verdict != "order"

    def step(self, frame: SensorFrame, recv_ns: int) -> GaitState:
        """Estimate one frame.

        Raises:
            FrameRefused: a reordered or repeated frame; the estimator is unchanged.
        """
        adm = self.admit(frame, recv_ns)
        if adm.verdict == "order":
            raise FrameRefused(adm.reason)
        t = adm.t
        if adm.verdict == "resync":
            self._t_offset = frame.t - t if math.isfinite(frame.t - t) else 0.0
            self.notes.append(f"session time resynchronised at {t:.3f} s: {adm.reason}")
        elif self._t_offset is None:
            self._t_offset = frame.t - t
        frame, implausible = frame.plausible()
        self.implausible += implausible
        # a channel's value for an estimator: NaN when absent, flags as 1.0 / 0.0 (inline: per frame)
        channels = {c: math.nan if (v := getattr(frame, c)) is None else float(v) for c in self._read}
        self._derive_velocities(channels, t)
        self.gain.before_step(t)
        e = self.stack.step(t, channels)
        self.events.extend(e.events)
        if e.fault:
            self.faults += 1
        restarted = e.fault in ("gap", "diverged", "lost", "resumed")
        for name in e.resets:
            if name != e.primary:
                self.notes.append(f"estimator {name} diverged at {t:.3f} s and was reset")
        if e.standing and not self._standing:
            self.notes.append(f"standing still from {t:.3f} s: phase held, torque to its standing value (0)")
        self._standing = e.standing
        if e.fault == "lost":
            self.last_lost = (t, self._lost_reason(e.primary))
        if restarted:
            what = {
                "gap": f"a gap of over {MAX_GAP_S:g} s",
                "diverged": f"{e.primary} diverged; reset",
                "lost": f"{e.primary} {self._lost_reason(e.primary)}; reset from the backup filter",
                "resumed": "walking resumed after standing still",
            }[e.fault]
            self.notes.append(f"estimator restarted at {t:.3f} s ({what}); assistance ramps up again")
            self.gain.restart(t)
        elif e.fault == "torque":
            self.notes.append(f"torque forced to 0 at {t:.3f} s: the torque model gave no finite value")
        self.last = e
        self.last_t = t
        self._last_recv_ns = recv_ns
        self._prev = (t, frame.foot_angle_deg, frame.shank_angle_deg, frame.thigh_angle_deg)
        torque = self.gain.torque(t, e.outputs, e.torque_Nm)
        return GaitState(
            seq=frame.seq,
            t=t,
            phase=e.phase,
            phase_rate=e.phase_rate,
            stride_length_m=e.stride_length_m,
            incline_deg=e.incline_deg,
            torque_Nm=torque,
            tbe_phase=e.tbe_phase,
            heel_strike=e.heel_strike,
            backup_reset=e.backup_reset,
            fault=bool(e.fault),
            # the frame's angles, else those the stack derived (the IMU front ends) for the leg view and plots
            foot_angle_deg=_sent_or_derived(frame.foot_angle_deg, channels["foot_angle_deg"]),
            shank_angle_deg=_sent_or_derived(frame.shank_angle_deg, channels["shank_angle_deg"]),
            thigh_angle_deg=_sent_or_derived(frame.thigh_angle_deg, channels["thigh_angle_deg"]),
            foot_pred_deg=e.foot_pred_deg,
            shank_pred_deg=e.shank_pred_deg,
            sent_ns=frame.sent_ns,
            recv_ns=recv_ns,
            sources=e.sources,
            torque_assumes=None if e.sources is None else dict(self.stack.torque_assumes),
        )

    def replaying(self, time_origin: float | None) -> None:
        """Go on with a recording's frames, restored from the state recorded at its start
        (:mod:`~gaitscope.sessions.formats.stack_state`): the frames carry session time ``frame.t - time_origin``
        (as the constructor's; None: 0 once a frame was stepped), are never resynchronised again (they were
        live), and have no receive time."""
        self._t_offset = 0.0 if time_origin is None and self._prev is not None else time_origin
        self.max_jump_s = math.inf
        self._min_next_t = -math.inf
        self._last_recv_ns = 0
        self.notes.clear()
        self.events.clear()

    def _lost_reason(self, name: str | None) -> str:
        """Why estimator ``name`` lost track (its ``lost_reason``, :mod:`gaitscope.estimators.lock`)."""
        if name is None or name not in self.stack.names:
            return "lost track"
        return str(getattr(self.stack.estimators[self.stack.names.index(name)], "lost_reason", "") or "lost track")

    def _derive_velocities(self, channels: dict[str, float], t: float) -> None:
        """Backward-difference velocities for a device without gyroscopes (``self._prev`` holds the last
        frame's angles of ``ANGLE_CHANNELS``, foot, shank, thigh, in its order); :func:`backward_difference`
        is the same rule over a whole column (replays and studies of files)."""
        prev = self._prev
        if prev is None or not t > prev[0]:
            return
        for (angle, vel), before in zip(ANGLE_CHANNELS.items(), prev[1:], strict=True):
            if before is not None and math.isnan(channels[vel]) and not math.isnan(channels[angle]):
                channels[vel] = (channels[angle] - before) / (t - prev[0])


def backward_difference(angle: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The velocity a live session derives for an angle a device sends without its rate
    (:meth:`FrameEstimator._derive_velocities`), over a whole column: ``(a[k] - a[k-1]) / (t[k] - t[k-1])``,
    NaN at the first sample and wherever either angle is missing (NaN). Not smoothed: a noisy angle gives a
    noisy rate (white angle noise of sd ``s`` at period ``dt`` gives about ``1.4 s / dt``); send the gyro
    rate when there is one.

    Args:
        angle: (n,) degrees, NaN where missing (out of its plausible range included).
        t: (n,) strictly increasing times (s).
    """
    out = np.full(angle.shape, np.nan)
    with np.errstate(invalid="ignore", over="ignore"):
        out[1:] = (angle[1:] - angle[:-1]) / (t[1:] - t[:-1])
    return out


def estimate(
    frames: list[SensorFrame],
    model: TrainedModel,
    leg_length: float,
    mass_kg: float,
    settings: SessionSettings,
    time_origin: float | None = None,
) -> list[GaitState]:
    """Run recorded frames through a fresh estimator (review re-runs, imports of raw logs).

    Recorded ``/sensor`` frames carry session time, so a re-run passes ``time_origin=0`` to keep it.
    A log's times are trusted (a pause stays a pause: no resynchronisation); reordered frames are
    skipped, as live. The stack is the settings' or every estimator the frames' channels allow.
    """
    period = (frames[-1].t - frames[0].t) / (len(frames) - 1) if len(frames) > 1 else DEFAULT_PERIOD
    est = FrameEstimator(
        model, leg_length, mass_kg, settings, period, time_origin, max_jump_s=math.inf, channels=channels_of(frames)
    )
    out = []
    for f in frames:
        if est.accepts(f):
            out.append(est.step(f, 0))
    return out


def _outputs_templates(name: str, outputs: Sequence[str]) -> tuple[str, str]:
    """%-format templates of an :class:`~gaitscope.sessions.schema.EstimatorOutputs` JSON: ``(healthy, failed)``,
    filled with ``(seq, t, *values)`` and ``(seq, t)``."""

    def text(values: str, failed: str) -> str:
        head = '{"seq":%d,"t":%r,"name":' + json.dumps(name).replace("%", "%%")
        return head + ',"values":{' + values + '},"failed":' + failed + "}"

    keys = [json.dumps(o).replace("%", "%%") for o in outputs]
    return text(",".join(f"{k}:%r" for k in keys), "false"), text(",".join(f"{k}:null" for k in keys), "true")


def _sent_or_derived(sent: float | None, derived: float) -> float | None:
    """A frame's value, else the stack's derived one when finite (None: neither)."""
    if sent is not None:
        return sent
    return derived if math.isfinite(derived) else None


#: The channels :meth:`FrameEstimator.step` fills for every frame (the rest only when an estimator reads them):
#: the phase EKF's, the segment angles and their velocities (:meth:`FrameEstimator._derive_velocities` derives
#: those a device does not send), the heel strike.
_STEPPED: Final[tuple[str, ...]] = tuple(
    dict.fromkeys((*SENSOR_CHANNELS, *(c for av in ANGLE_CHANNELS.items() for c in av), HEEL_STRIKE))
)


#: Left out of a recorded sensor frame's own JSON: its time, which the recording puts first in session time.
_T: Final = {"t"}
_TORQUE: Final = '{"type":"torque","seq":%d,"t":%r,"torque_Nm":%r}'


def frame_json(frame: SensorFrame, t: float) -> bytes:
    """The JSON of ``frame`` at session time ``t`` (s) without its absent channels, as a recording holds
    a sensor frame: built from the frame's own JSON rather than from a copy of the model (per sample, the
    copy cost more than the rest of the recording; ``tests/sessions/test_estimation.py`` reads it back)."""
    return b'{"t":%r,%s' % (t, frame.model_dump_json(exclude_none=True, exclude=_T).encode()[1:])


def torque_json(seq: int, t: float, torque_Nm: float) -> str:
    """The JSON of ``TorqueCommand(seq=seq, t=t, torque_Nm=torque_Nm)``, sent to a device and recorded
    once per sample: a format string is a fifth of the model's cost (``tests/sessions/test_estimation.py``
    reads it back as the model). A torque of -0.0 is sent as 0.0 (``+ 0.0``): a device need not know signed zeros."""
    torque_Nm = torque_Nm + 0.0
    if math.isfinite(t) and math.isfinite(torque_Nm):  # %r of a finite float is valid JSON
        return _TORQUE % (seq, t, torque_Nm)
    return schema.TorqueCommand(seq=seq, t=t, torque_Nm=torque_Nm).model_dump_json()
