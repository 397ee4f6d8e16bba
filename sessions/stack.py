"""A session's estimator stack: several estimators on one sensor stream, one of them driving the torque.

Every estimator implements :class:`gaitscope.estimators.protocol.Estimator`; which ones a session runs is chosen at
its start (:mod:`gaitscope.sessions.registry`). Per sample each estimator gets its declared input channels and
returns its declared outputs; an output that is itself a channel (``heel_strike`` of the detector or the
phase EKF) fills that channel for the estimators after it when the source does not send it.

The **primary** estimator's phase (and its stride length and incline when it has them, else
:data:`NOMINAL_STRIDE` leg lengths on level ground: :attr:`EstimatorStack.torque_assumes`) drives the torque
profile, unless the primary declares a ``torque_Nm`` output of its own (seed 003's ``gp_ekf``: its control
surface over stance phase and phase rate, whose ``phase`` is the stance phase, not the gait phase the profile is
indexed by). Then its own command wins: ``torque_Nm`` times the session's torque gain, clamped to
``[0, max_torque]`` and taken to 0 as the estimator says the walker stands (``standing``), like the
profile's. Switching the primary (:meth:`EstimatorStack.set_primary`) blends the command from the old
primary's to the new one's over ``blend_s`` seconds, so the torque never steps.

Isolation: an estimator that raises, returns a non-finite output (or the wrong number of them), or
whose covariance is non-finite or has a variance outside ``[0, max_variance]`` is marked failed, with
the reason; it is not stepped again, and the others and the torque go on. A failed primary hands the
torque to the fallback (:data:`FALLBACK`, the timing-based estimate) if it is healthy, else to zero
torque, blending from the last command in the same way. Every such change is reported in
:attr:`StackSample.events` for the session's event log.

What a sample reports is what some estimator estimated, never a value assumed for it: each quantity of
:data:`REPORTED` comes from the primary when it estimates it, else from the first healthy estimator in stack
order that does (:attr:`EstimatorStack.sources` names which), else it is None, "not estimated". The nominal
values the torque profile assumes for a primary without a stride length or incline drive the torque only; they
are stated in :attr:`EstimatorStack.torque_assumes`, not reported as the gait state.

Pure computation (no I/O, no clocks); the torque is always a finite number in ``[0, max_torque]``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from operator import itemgetter
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from gaitscope.estimators import _kernels
from gaitscope.estimators.phase_ekf import EKFConfig
from gaitscope.estimators.protocol import HEEL_STRIKE, MAX_GAP_S, Estimator, input_names, output_names
from gaitscope.estimators.torque import TorqueProfile
from gaitscope.sessions.schema import CHANNELS, PRIMARY_BLEND_S

__all__ = ["FALLBACK", "MAX_VARIANCE", "NOMINAL_STRIDE", "OWN_TORQUE", "REPORTED", "EstimatorStack", "StackSample"]

#: Takes the torque when the primary fails (if it is in the stack and healthy; else the torque is 0).
FALLBACK: Final = "tbe"
#: Stride length (leg lengths) the torque profile assumes for a primary that does not estimate it: the
#: phase EKF's initial value (seed 000: 1.3); the incline is then 0 (level ground).
NOMINAL_STRIDE: Final = EKFConfig().initial_stride_length
#: Largest variance a healthy estimator's covariance may hold (as the phase EKF's health limit).
MAX_VARIANCE: Final = 1e3
#: An estimator's output holding its own torque command (N m), which drives the torque when it is primary.
OWN_TORQUE: Final = "torque_Nm"
#: Outputs named as a sensor channel fill that channel for the estimators after them (``heel_strike``).
_CHANNELS: Final = frozenset(CHANNELS)
_DIVERGED: Final = 2.0  # gaitscope.estimators.protocol.FAULTS.index("diverged")
_LOST: Final = 4.0  # FAULTS.index("lost"): reset from a backup, torque 0 on that sample as for "diverged"
#: An IMU front end's ``imu_code`` when its sensor sent nothing usable (gaitscope.estimators.imu_frontend.CODES):
#: it holds its last angle and rate for its own continuity, but derives no channel for the others.
_IMU_MISSING: Final = 1.0
_RESUMED: Final = 5.0  # FAULTS.index("resumed"): restarted as walking resumed after standing still
#: The quantities a sample reports (its :class:`StackSample` fields, each an estimator output of that name):
#: the primary's when it has the output, else the first healthy estimator's in stack order that has it, else
#: None (not estimated). The phase is the primary's alone (None without a primary).
REPORTED: Final = ("phase_rate", "stride_length_m", "incline_deg", "foot_pred_deg", "shank_pred_deg")


def _reader(names: tuple[str, ...]) -> Callable[[Mapping[str, float]], tuple[float, ...]]:
    """What reads the values of ``names`` from a mapping holding them all, as a tuple in that order. Not part
    of a captured state (:meth:`EstimatorStack.__getstate__`): made again from the names when it is loaded."""
    if len(names) > 1:
        return itemgetter(*names)  # a tuple for two names or more
    if names:
        (only,) = names
        return lambda values: (values[only],)
    return lambda values: ()


@dataclass
class StackSample:
    """What the stack made of one sample.

    Attributes:
        outputs: per estimator in stack order, its outputs (None once it has failed).
        torque_Nm: the command, finite and within ``[0, max_torque]``.
        primary: the estimator driving it (None: none, the torque blends to 0).
        phase: the primary's (None: no primary).
        phase_rate, stride_length_m, incline_deg, foot_pred_deg, shank_pred_deg: the primary's when it
            estimates them, else the first healthy estimator's that does, else None (not estimated; see
            :data:`REPORTED` and :attr:`EstimatorStack.sources`). Not what the torque profile assumed.
        tbe_phase: the ``tbe`` estimator's phase (None without a healthy one).
        heel_strike: the heel-strike channel (the source's, else the first estimator's to derive it).
        backup_reset: the primary's when it has it.
        sources: :attr:`EstimatorStack.sources` on the first sample and wherever they changed (a primary
            switch, a failure, :meth:`EstimatorStack.announce_sources`), else None (unchanged).
        standing: the primary says the walker stands still (its ``standing`` output, :mod:`gaitscope.estimators.lock`).
        fault: ``""``; ``"gap"`` (samples further apart than ``max_gap_s``: the estimators restarted);
            ``"diverged"`` (the primary reset its state: torque 0); ``"lost"`` (the primary lost track and
            reset from a backup: torque 0); ``"resumed"`` (the primary restarted as walking resumed after
            standing still); ``"failed"`` (the primary failed here); ``"torque"`` (the command was not a
            finite number within the bound and was forced to 0).
        resets: estimators that reset a diverged state at this sample.
        events: what happened that belongs in the session's event log (failures, primary switches).
    """

    outputs: list[NDArray[np.float64] | None]
    torque_Nm: float
    primary: str | None
    phase: float | None
    phase_rate: float | None
    stride_length_m: float | None
    incline_deg: float | None
    tbe_phase: float | None
    heel_strike: bool
    backup_reset: bool
    foot_pred_deg: float | None
    shank_pred_deg: float | None
    standing: bool = False
    sources: dict[str, str] | None = None
    fault: str = ""
    resets: list[str] = field(default_factory=list)
    events: list[str] = field(default_factory=list)


class EstimatorStack:
    """Runs a session's estimators on each sample and computes the torque from the primary's outputs.

    Args:
        estimators: the stack, in run order (names unique).
        torque: the torque profile.
        leg_length, mass_kg: the subject's (m, kg).
        primary: the estimator whose phase drives the torque (it must estimate a phase).
        torque_gain, max_torque: assistance (:meth:`retune_torque` changes them).
        blend_s: how long a switch of the primary blends the command (s; 0: at once).
        fallback: takes the torque from a failed primary (if healthy), else the torque goes to 0.
        max_variance: a covariance with a larger variance counts as diverged.
        max_gap_s: samples further apart count as a gap (``fault="gap"``).
        labels: each estimator's name on screen, for the events' words (default: its name).

    Attributes:
        names: the estimators' names in run order; outputs: each one's output names.
        failed: failed estimators and why (they are not stepped again).
        primary: the estimator driving the torque now (None: none).
        sources: which estimator each reported quantity comes from now (``phase`` and those of
            :data:`REPORTED`); a quantity absent is not estimated.
        torque_assumes: the values the torque profile takes for what the primary does not estimate
            (``stride_length_m`` in m, ``incline_deg``); empty when it estimates both or drives the torque
            with its own command.
    """

    def __init__(
        self,
        estimators: Sequence[Estimator],
        torque: TorqueProfile,
        leg_length: float,
        mass_kg: float,
        *,
        primary: str,
        torque_gain: float = 1.0,
        max_torque: float = 30.0,
        blend_s: float = PRIMARY_BLEND_S,
        fallback: str = FALLBACK,
        max_variance: float = MAX_VARIANCE,
        max_gap_s: float = MAX_GAP_S,
        labels: Mapping[str, str] | None = None,
    ):
        self.estimators = list(estimators)
        self.names = tuple(e.name for e in self.estimators)
        if len(set(self.names)) != len(self.names):
            raise ValueError(f"estimator names must be unique, got {self.names}")
        if not (math.isfinite(blend_s) and blend_s >= 0):
            raise ValueError(f"blend_s must be a number of seconds >= 0, got {blend_s}")
        self.outputs = tuple(output_names(e) for e in self.estimators)
        self._inputs = [input_names(e) for e in self.estimators]
        #: every input channel missing (NaN), for a sample's values to be laid over; per estimator, what reads
        #: its ``z`` from them in its order (a tuple)
        self._blank = dict.fromkeys((c for names in self._inputs for c in names), math.nan)
        self._read_z = [_reader(names) for names in self._inputs]  # made again from _inputs on load (__setstate__)
        self._index = [{n: i for i, n in enumerate(outs)} for outs in self.outputs]
        self._derived = [[(i, n) for i, n in enumerate(outs) if n in _CHANNELS] for outs in self.outputs]
        self._imu_code = [index.get("imu_code") for index in self._index]  # a front end's problem code
        self._fault = [index.get("fault") for index in self._index]  # where each one's fault code is
        self._shape = [(len(outs),) for outs in self.outputs]  # of a step's result
        #: each estimator's own torque command output (``torque_Nm``), None for those without one
        self._own_torque = [idx.get(OWN_TORQUE) for idx in self._index]
        self._position = {n: k for k, n in enumerate(self.names)}
        self.labels = {n: (labels or {}).get(n, n) for n in self.names}
        self.torque = torque
        self.leg_length = leg_length
        self.mass_kg = mass_kg
        self.blend_s = blend_s
        self.fallback = fallback
        self.max_variance = max_variance
        self.max_gap_s = max_gap_s
        self.failed: dict[str, str] = {}
        self.torque_gain = 0.0
        self.max_torque = 0.0
        self.retune_torque(torque_gain, max_torque)
        self.check_primary(primary)
        self.primary: str | None = primary
        #: The primary asked for (the session's setting); ``primary`` differs once it failed.
        self.requested = primary
        self._blend: tuple[str | None, float, float] | None = None  # (from, held command, start time)
        self._t: float | None = None
        self._last_torque = 0.0
        self._pending: list[str] = []
        #: (field, estimator position, output index) of each reported quantity; None: to be made again
        self._reading: list[tuple[str, int, int]] | None = None
        self.sources: dict[str, str] = {}
        self.torque_assumes: dict[str, float] = {}
        self._announce = True

    # --- settings -------------------------------------------------------------------------------
    def retune_torque(self, gain: float, bound: float) -> None:
        """Assistance from the next sample on: gain (x the profile) and bound (N m)."""
        if not (math.isfinite(gain) and gain >= 0 and math.isfinite(bound) and 0 <= bound <= 200):
            raise ValueError(f"torque gain {gain} and bound {bound} N m must be >= 0 and <= 200 N m")
        self.torque_gain, self.max_torque = gain, bound

    def retune(self, **params: float) -> None:
        """Give each healthy estimator the parameters it declares tunable; one that raises has failed."""
        for est in self.estimators:
            mine = {k: v for k, v in params.items() if k in est.tunables}
            if mine and est.name not in self.failed:
                try:
                    est.retune(**mine)
                except Exception as e:  # isolation: its failure must not stop the others
                    self._fail(est.name, f"retune raised {type(e).__name__}: {e}")

    def check_primary(self, name: str) -> None:
        """Raise ValueError unless ``name`` can drive the torque (in the stack, a phase, not failed)."""
        if name not in self._position:
            raise ValueError(f"{name} is not in the session's stack ({', '.join(self.names)})")
        if "phase" not in self._index[self._position[name]]:
            raise ValueError(f"{name} estimates no phase, so it cannot drive the torque")
        if name in self.failed:
            raise ValueError(f"{name} has failed ({self.failed[name]}); it cannot drive the torque")

    def set_primary(self, name: str) -> None:
        """Hand the torque to ``name`` from the next sample on, blending over ``blend_s``.

        Raises:
            ValueError: not in the stack, no phase output, or failed; nothing changed.
        """
        self.check_primary(name)
        self.requested = name
        if name != self.primary:
            self._switch(name)

    def announce_sources(self) -> None:
        """Report :attr:`sources` on the next sample even if unchanged (a new recording starts with them)."""
        self._announce = True

    def take_events(self) -> list[str]:
        """Events of failures outside :meth:`step` (a retune that raised), once."""
        events, self._pending = self._pending, []
        return events

    def _switch(self, to: str | None) -> None:
        """Blend from the command now (the old primary's, live, when healthy and no blend is running;
        else the last command, held and fading out) to ``to``'s."""
        old = self.primary
        live = old is not None and old not in self.failed and self._blend is None
        start = self._t if self._t is not None else 0.0
        self._blend = (old if live else None, self._last_torque, start) if self.blend_s > 0 else None
        self.primary = to
        self._reading = None

    # --- per sample -----------------------------------------------------------------------------
    def __getstate__(self) -> dict[str, Any]:
        """The state a re-run restores (``sessions/formats/stack_state.py``): everything but the input readers,
        which are functions its loader refuses; :meth:`__setstate__` makes them again from the inputs' names."""
        state = dict(self.__dict__)
        del state["_read_z"]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._read_z = [_reader(names) for names in self._inputs]

    def step(self, t: float, channels: dict[str, float]) -> StackSample:
        """One sample at session time ``t`` (s, increasing).

        Args:
            channels: the source's channel values by name (NaN or absent: missing); derived channels
                are added to it.
        """
        gap = self._t is not None and t - self._t > self.max_gap_s
        outputs: list[NDArray[np.float64] | None] = []
        resets: list[str] = []
        primary_failed = False
        primary_code = ""
        values = self._blank.copy()  # every input: the sample's value, else NaN (missing)
        values.update(channels)
        for k, est in enumerate(self.estimators):
            name = self.names[k]
            if name in self.failed:
                outputs.append(None)
                continue
            z = np.array(self._read_z[k](values), dtype=np.float64)
            try:
                y = np.asarray(est.step(t, z), dtype=np.float64)
                reason = self._unhealthy(k, y)
            except Exception as e:  # isolation: an estimator's bug must not stop the others or the torque
                y, reason = np.empty(0), f"raised {type(e).__name__}: {e}"
            if reason:
                primary_failed = primary_failed or name == self.primary
                self._fail(name, reason, t)
                outputs.append(None)
                continue
            outputs.append(y)
            code = self._imu_code[k]
            if code is None or y[code] != _IMU_MISSING:  # a held reading is not a measurement
                for i, channel in self._derived[k]:
                    if math.isnan(channels.get(channel, math.nan)):
                        channels[channel] = values[channel] = float(y[i])
            fault = self._fault[k]
            if fault is not None and y[fault] >= _DIVERGED:
                code = y[fault]
                if code == _DIVERGED or code == _LOST:
                    resets.append(name)
                if name == self.primary and (code == _LOST or code == _RESUMED):
                    primary_code = "lost" if code == _LOST else "resumed"
        sample = self._sample(t, outputs, channels)
        sample.events, self._pending = self._pending, []
        sample.resets = resets
        if primary_failed:
            sample.fault = "failed"
        elif primary_code:
            sample.fault = primary_code
        elif self.primary in resets:
            sample.fault = "diverged"
        elif gap:
            sample.fault = "gap"
        if not math.isfinite(sample.torque_Nm):
            sample.torque_Nm, sample.fault = 0.0, sample.fault or "torque"
        # within the bound: a blend from a command made under a higher bound is clamped, not zeroed
        sample.torque_Nm = min(max(sample.torque_Nm, 0.0), self.max_torque)
        self._last_torque = sample.torque_Nm
        self._t = t
        return sample

    def _unhealthy(self, k: int, y: NDArray[np.float64]) -> str:
        """Why estimator ``k``'s step result or covariance counts as a failure ("" if it does not)."""
        names = self.outputs[k]
        if y.shape != self._shape[k]:
            return f"returned {y.size} values for its {len(names)} outputs"
        P = self.estimators[k].covariance
        if P is None:
            if _kernels.finite_sum(y):
                return ""  # healthy, found in compiled code; the reasons below say why not
        elif P.ndim == 2 and P.shape[0] == P.shape[1] and _kernels.outputs_ok(y, P, self.max_variance):
            return ""
        # On a handful of numbers, Python's sum of a list is several times cheaper than numpy's
        # reductions; a sum is finite only if every term is (it may also overflow near 1e308: such
        # values count as failed too).
        values = y.tolist()
        if not math.isfinite(sum(values)):
            bad = [n for n, v in zip(names, values, strict=True) if not math.isfinite(v)] or list(names)
            return f"returned a non-finite {', '.join(bad)}"
        if P is not None:
            flat = P.ravel().tolist()
            if not math.isfinite(sum(flat)):
                return "its covariance is not finite"
            d = flat[:: P.shape[0] + 1]
            lo, hi = min(d), max(d)
            if lo < 0 or hi > self.max_variance:
                return f"its covariance diverged (variances {lo:.3g} .. {hi:.3g})"
        return ""

    def _fail(self, name: str, reason: str, t: float | None = None) -> None:
        """Mark ``name`` failed; a failed primary hands the torque to the fallback, else to none."""
        self.failed[name] = reason
        self._reading = None
        at = "" if t is None else f" at {t:.3f} s"
        label = self.labels.get(name, name)
        self._pending.append(f"estimator {label} failed{at}: {reason}")
        if name == self.primary:
            fb = self.fallback
            healthy = fb in self._position and fb not in self.failed and "phase" in self._index[self._position[fb]]
            self._switch(fb if healthy else None)
            then = f"the torque now follows {self.labels[fb]}" if healthy else "no fallback, the torque ramps down to 0"
            self._pending.append(f"primary estimator {label} failed{at}: {then}")

    def _command(self, name: str, outputs: list[NDArray[np.float64] | None]) -> float:
        """The command estimator ``name``'s outputs make (0 where it reset a diverged state): its own
        ``torque_Nm`` times the gain when it has one, else the torque profile at its phase; to 0 standing."""
        k = self._position[name]
        y, idx = outputs[k], self._index[k]
        if y is None:
            return 0.0
        fault = idx.get("fault")
        if fault is not None and (y[fault] == _DIVERGED or y[fault] == _LOST):
            return 0.0
        i = idx.get("standing")
        still = 0.0 if i is None else float(y[i])
        if not 0.0 <= still <= 1.0:  # NaN too: walking
            still = 0.0
        own = self._own_torque[k]
        if own is not None:  # its own control surface; NaN or infinite is caught by step() (torque 0)
            command = min(max(float(y[own]) * self.torque_gain, 0.0), self.max_torque)
            return command * (1.0 - still)
        stride = idx.get("stride_length_m")
        incline = idx.get("incline_deg")
        l_norm = NOMINAL_STRIDE if stride is None else float(y[stride]) / self.leg_length
        r = 0.0 if incline is None else float(y[incline])
        command = self.torque.torque_at(
            float(y[idx["phase"]]), l_norm, r, self.mass_kg * self.torque_gain, self.max_torque
        )
        return command * (1.0 - still)  # standing still: to the standing value (0), ramped by the estimator

    def _sample(self, t: float, outputs: list[NDArray[np.float64] | None], channels: dict[str, float]) -> StackSample:
        primary = self.primary
        new = 0.0 if primary is None else self._command(primary, outputs)
        torque = new
        if self._blend is not None:
            old, held, t0 = self._blend
            w = (t - t0) / self.blend_s
            if w >= 1.0 or not math.isfinite(w):
                self._blend = None
            else:
                before = held if old is None or old in self.failed else self._command(old, outputs)
                torque = (1.0 - w) * before + w * new
        hs = channels.get(HEEL_STRIKE, math.nan)
        reading = self._reading if self._reading is not None else self._read_plan()
        values: dict[str, float | None] = dict.fromkeys(REPORTED)
        values["phase"] = None
        for name, k, i in reading:  # a live session does this 200 times a second: no more than the reads
            y = outputs[k]
            if y is not None:
                values[name] = float(y[i])
        backup_reset = standing = False
        if primary is not None:
            k = self._position[primary]
            y, idx = outputs[k], self._index[k]
            if y is not None:
                b, st = idx.get("backup_reset"), idx.get("standing")
                backup_reset = b is not None and y[b] > 0.5
                standing = st is not None and y[st] > 0.5
        sources = None
        if self._announce:
            sources, self._announce = dict(self.sources), False
        return StackSample(
            outputs=outputs,
            torque_Nm=torque,
            primary=primary,
            phase=values["phase"],
            phase_rate=values["phase_rate"],
            stride_length_m=values["stride_length_m"],
            incline_deg=values["incline_deg"],
            tbe_phase=self._value("tbe", "phase", outputs),
            heel_strike=bool(hs > 0.5),
            backup_reset=backup_reset,
            standing=standing,
            foot_pred_deg=values["foot_pred_deg"],
            shank_pred_deg=values["shank_pred_deg"],
            sources=sources,
        )

    def _read_plan(self) -> list[tuple[str, int, int]]:
        """Where each reported quantity is read from now (see :data:`REPORTED`); sets :attr:`sources` and
        :attr:`torque_assumes` to match."""
        primary = self.primary
        order = [n for n in ((primary,) if primary is not None else ()) + self.names if n not in self.failed]
        reading: list[tuple[str, int, int]] = []
        sources: dict[str, str] = {}
        if primary is not None and primary not in self.failed:
            k = self._position[primary]
            reading.append(("phase", k, self._index[k]["phase"]))
            sources["phase"] = primary
        for quantity in REPORTED:
            for name in order:
                k = self._position[name]
                i = self._index[k].get(quantity)
                if i is not None:
                    reading.append((quantity, k, i))
                    sources[quantity] = name
                    break
        assumes: dict[str, float] = {}
        if primary is not None and self._own_torque[self._position[primary]] is None:
            idx = self._index[self._position[primary]]
            if "stride_length_m" not in idx:
                assumes["stride_length_m"] = NOMINAL_STRIDE * self.leg_length
            if "incline_deg" not in idx:
                assumes["incline_deg"] = 0.0
        if sources != self.sources or assumes != self.torque_assumes:
            self._announce = True
        self.sources, self.torque_assumes, self._reading = sources, assumes, reading
        return reading

    def _value(self, name: str, output: str, outputs: list[NDArray[np.float64] | None]) -> float | None:
        """Estimator ``name``'s ``output`` at this sample (None: not in the stack, no such output, failed)."""
        k = self._position.get(name)
        if k is None:
            return None
        y, i = outputs[k], self._index[k].get(output)
        return None if y is None or i is None else float(y[i])
