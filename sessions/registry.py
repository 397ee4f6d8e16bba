"""Which estimators a session runs: the registry, and a stack chosen against a source's channels.

A session's stack is chosen at its start (:func:`resolve`): the estimators its settings name, or by
default every registered one (:data:`ESTIMATORS`, less the :data:`OPT_IN` ones, and less the
:data:`DERIVERS` whose channels the source already sends) whose required channels the source sends. A named
one the source cannot feed refuses the start, naming the missing channels (:class:`MissingChannels`).
The order of :data:`ESTIMATORS` is the order a stack runs them in: a channel an estimator derives
(``heel_strike``) reaches only those after it. :func:`build_stack` wraps the chosen estimators in a
:class:`~gaitscope.sessions.stack.EstimatorStack`.

What each registered estimator is, for screens and for checking a log before anything is built
(:data:`DECLARED`: its name on screen, required inputs and outputs), and which of them a log's channels
can feed (:func:`feeds`): a review offers those to re-run.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Iterable, Iterator, Mapping, Sequence
from collections.abc import Set as AbstractSet
from dataclasses import dataclass
from functools import cache, partial
from importlib import resources
from typing import Any, Final, TypeVar

import numpy as np

from gaitscope.estimators import (
    com_kinematics,
    detector,
    fingerprint,
    gp_ekf_estimator,
    heel_strike,
    imu_frontend,
    intent_estimator,
    phase_ekf_estimator,
    sdre_estimator,
    tbe,
)
from gaitscope.estimators.com_kinematics import KinematicCoM
from gaitscope.estimators.descriptor import Descriptor
from gaitscope.estimators.detector import HeelStrikeDetector
from gaitscope.estimators.fingerprint import FingerprintEKF, Mode
from gaitscope.estimators.gp_ekf_estimator import (
    COHORT_COLUMNS,
    ControlSurface,
    GPEKFEstimator,
    build_default,
    load_default,
)
from gaitscope.estimators.gp_models import GPModelSet
from gaitscope.estimators.heel_strike import HeelStrikeBackup
from gaitscope.estimators.imu_frontend import SEGMENTS as IMU_SEGMENTS
from gaitscope.estimators.imu_frontend import FrontEndConfig, ImuFrontEnd
from gaitscope.estimators.intent import COHORT, BKFConfig
from gaitscope.estimators.intent_estimator import IntentEstimator
from gaitscope.estimators.phase_ekf_estimator import PhaseEKFEstimator
from gaitscope.estimators.pipeline import PipelineConfig, TrainedModel
from gaitscope.estimators.protocol import ANGLE_CHANNELS, Estimator, Output, output_names
from gaitscope.estimators.sdre_estimator import SDREKnee
from gaitscope.estimators.tbe import TimingBasedEstimator
from gaitscope.sessions.schema import CHANNELS, PRIMARY_BLEND_S, SensorFrame, missing_channels
from gaitscope.sessions.stack import EstimatorStack

__all__ = [
    "DECLARED",
    "DERIVERS",
    "DESCRIPTORS",
    "ESTIMATORS",
    "GP_EKF_MODEL_NAME",
    "OPT_IN",
    "Declared",
    "Feed",
    "MissingChannels",
    "StackContext",
    "Unavailable",
    "build_stack",
    "channels_of",
    "choose_primary",
    "descriptors",
    "feeds",
    "gp_ekf_default",
    "redundant",
    "resolve",
    "streamed",
]

_CHANNELS: Final = frozenset(CHANNELS)
_V = TypeVar("_V")


@dataclass(frozen=True)
class StackContext:
    """What an estimator of a session is built from: the trained models, the subject, the sample period,
    and the subject's personalized gait fingerprint (seed 004; None until one is calibrated) and speed-change
    intent model (seed 001; None: the cohort's kappa)."""

    model: TrainedModel
    leg_length: float
    mass_kg: float
    sample_period: float
    fingerprint: tuple[float, ...] | None = None
    intent: BKFConfig | None = None


class Unavailable(ValueError):
    """An estimator that what the session has cannot build (the model has no fingerprint map, the subject no
    calibrated fingerprint); the message says why and what to do."""


def _fingerprint_ekf(c: StackContext, mode: Mode) -> FingerprintEKF:
    """Seed 004's filter on the model's map: ``avg`` and ``gf`` need the map, ``ls`` also the subject's
    fingerprint."""
    fmap = c.model.fingerprints
    if fmap is None:
        raise Unavailable("the model has no fingerprint map (it was trained without thigh angles)")
    g = None
    if mode == "ls":
        if c.fingerprint is None:
            raise Unavailable("the subject has no personalized fingerprint yet: calibrate one first")
        if len(c.fingerprint) != fmap.n_components:
            raise Unavailable(
                f"the subject's fingerprint has {len(c.fingerprint)} components and the model's map "
                f"{fmap.n_components}: calibrate again with this model"
            )
        g = np.array(c.fingerprint, dtype=np.float64)
    return FingerprintEKF(fmap, mode=mode, g=g)


#: The GP-EKF's default models (seed 003) when shipped: ``default_arrays(*build_default(...))`` of
#: ``gaitscope.estimators.gp_ekf_estimator`` saved with ``np.savez``. Without it they are fitted on first use to
#: :data:`~gaitscope.sessions.synth.cohort.GP_EKF_COHORT` (about 3 s with GPy's import, once per process).
GP_EKF_MODEL_NAME: Final = "gp_ekf_default.npz"


@cache
def gp_ekf_default() -> tuple[GPModelSet, ControlSurface]:
    """The GP-EKF's first observation models and its torque control surface (see :data:`GP_EKF_MODEL_NAME`)."""
    path = resources.files("gaitscope.sessions") / "data" / GP_EKF_MODEL_NAME
    if path.is_file():
        with resources.as_file(path) as file, np.load(file) as arrays:
            return load_default(dict(arrays))
    from gaitscope.sessions.synth.cohort import GP_EKF_COHORT, generate_cohort  # here: pandas, the cohort

    frame = generate_cohort(GP_EKF_COHORT)
    return build_default({c: frame[c].to_numpy() for c in COHORT_COLUMNS})


def _imu_front_end(segment: str, c: StackContext) -> ImuFrontEnd:
    return ImuFrontEnd(segment, FrontEndConfig.for_segment(segment, sample_period=c.sample_period))


def _phase_ekf(c: StackContext) -> PhaseEKFEstimator:
    return PhaseEKFEstimator(c.model, PipelineConfig(leg_length=c.leg_length, body_mass_kg=c.mass_kg), c.sample_period)


def _hs_backup(c: StackContext) -> HeelStrikeBackup:
    return HeelStrikeBackup.standalone(c.model.coef, c.model.noise, c.leg_length, channel_mask=c.model.channel_mask)


#: Every estimator a session can stack, one line each, in the order a stack runs them (a channel an
#: estimator derives reaches only those after it): its descriptor (beside its class: what it is, reads,
#: outputs, tunes, plots and is for) and how a session builds it. Everything else here and in the browser's
#: ``wire.js`` is derived from this list (:data:`ESTIMATORS`, :data:`DECLARED`, :data:`OPT_IN`, :data:`DERIVERS`).
#: The standalone heel-strike backup is opt-in as it duplicates the one inside ``phase_ekf`` (which uses it to
#: reset the filter) at about half of the stack's time per sample; the GP-EKF (seed 003) as it estimates the
#: stance phase, not the gait phase the torque profile follows, and retrains online.
DESCRIPTORS: list[Descriptor] = [
    # the IMU front ends first: the angle channels they derive feed every estimator after them
    *(imu_frontend.descriptor(seg).built_by(partial(_imu_front_end, seg)) for seg in IMU_SEGMENTS),
    detector.DESCRIPTOR.built_by(lambda c: HeelStrikeDetector()),
    phase_ekf_estimator.DESCRIPTOR.built_by(_phase_ekf),
    tbe.DESCRIPTOR.built_by(lambda c: TimingBasedEstimator()),
    heel_strike.DESCRIPTOR.built_by(_hs_backup),
    fingerprint.descriptor("avg").built_by(lambda c: _fingerprint_ekf(c, "avg")),
    fingerprint.descriptor("ls").built_by(lambda c: _fingerprint_ekf(c, "ls")),
    fingerprint.descriptor("gf").built_by(lambda c: _fingerprint_ekf(c, "gf")),
    com_kinematics.DESCRIPTOR.built_by(lambda c: KinematicCoM(c.leg_length)),
    intent_estimator.DESCRIPTOR.built_by(lambda c: IntentEstimator(c.leg_length, c.intent or COHORT)),
    sdre_estimator.DESCRIPTOR.built_by(lambda c: SDREKnee(c.leg_length, c.mass_kg)),
    gp_ekf_estimator.DESCRIPTOR.built_by(lambda c: GPEKFEstimator(*gp_ekf_default(), mass_kg=c.mass_kg)),
]


def descriptors() -> dict[str, Descriptor]:
    """:data:`DESCRIPTORS` by name, as the list is now (a test may add to it for a while).

    Raises:
        ValueError: two descriptors of one name, or one without a factory.
    """
    out: dict[str, Descriptor] = {}
    for d in DESCRIPTORS:
        if d.name in out:
            raise ValueError(f"two registered estimators are named {d.name}")
        if d.factory is None:
            raise ValueError(f"{d.name} is registered without a factory (Descriptor.built_by)")
        out[d.name] = d
    return out


@dataclass(frozen=True)
class Declared:
    """A registered estimator as its class declares it, known without building it (no model needed)."""

    label: str  #: its name on screen (the registry name is the machine name)
    inputs: tuple[str, ...]  #: channels it requires (``Estimator.inputs``)
    outputs: tuple[Output, ...]  #: ``(name, unit)`` in the order it returns them (``Estimator.outputs``)
    inputs_any: tuple[str, ...] = ()  #: it needs at least one of these (:attr:`Descriptor.inputs_any`)

    @property
    def phased(self) -> bool:
        """It estimates a phase (an output ``phase``): it can drive the torque."""
        return any(o == "phase" for o, _ in self.outputs)

    def lacking(self, available: Collection[str]) -> list[str]:
        """What a source providing ``available`` lacks to run it: each required channel it does not
        provide, and, when it provides none of :attr:`inputs_any`, those joined by "or" as one entry
        (``foot_angle_deg or shank_angle_deg``). Empty: it can run. The one rule of what a source can feed,
        for live sessions, uploads, re-runs and ``gaitscope replay``."""
        out = missing_channels(self.inputs, available)
        if self.inputs_any and not any(c in available for c in self.inputs_any):
            out.append(" or ".join(self.inputs_any))
        return out


class _ByName(Mapping[str, _V]):
    """A read-only view by name of :data:`DESCRIPTORS` as it is when read (so that a descriptor a test
    adds for a while shows everywhere at once)."""

    def __init__(self, value: Callable[[Descriptor], _V]):
        self._value = value

    def __getitem__(self, name: str) -> _V:
        return self._value(descriptors()[name])

    def __iter__(self) -> Iterator[str]:
        return iter(descriptors())

    def __len__(self) -> int:
        return len(DESCRIPTORS)


class _Names(AbstractSet[str]):
    """A read-only set view of the names of :data:`DESCRIPTORS` that have a property, as it is when read."""

    def __init__(self, has: Callable[[Descriptor], bool]):
        self._has = has

    def _names(self) -> frozenset[str]:
        return frozenset(d.name for d in DESCRIPTORS if self._has(d))

    def __contains__(self, name: object) -> bool:
        return name in self._names()

    def __iter__(self) -> Iterator[str]:
        return iter(self._names())

    def __len__(self) -> int:
        return len(self._names())

    @classmethod
    def _from_iterable(cls, it: Iterable[Any]) -> frozenset[Any]:
        return frozenset(it)


#: Every estimator a session can stack, by name, in the order a stack runs them: how a session builds it.
ESTIMATORS: Final[Mapping[str, Callable[[StackContext], Estimator]]] = _ByName(lambda d: d.build)
#: Every registered estimator (same order) as its class declares it, with its name on screen.
#: ``tests/sessions/test_registry.py`` checks that each built estimator declares the same.
DECLARED: Final[Mapping[str, Declared]] = _ByName(
    lambda d: Declared(d.label, d.inputs, d.declared_outputs, d.inputs_any)
)
#: Registered but run only when a session names them (:attr:`Descriptor.opt_in`).
OPT_IN: Final[AbstractSet[str]] = _Names(lambda d: d.opt_in)
#: Registered to derive channels a source may not send (sensor front ends, :attr:`Descriptor.derives`): a
#: default stack leaves one out when the source already sends (or an earlier estimator derives) every channel
#: it would derive, since a sent channel wins over a derived one and its work would be thrown away.
DERIVERS: Final[AbstractSet[str]] = _Names(lambda d: d.derives)


def streamed(name: str) -> frozenset[str]:
    """The outputs of estimator ``name`` a browser gets live (:attr:`Descriptor.streamed`); of one not registered
    (a test double, an experiment: ``build_stack``'s ``extra``), those of these names any registered one streams."""
    found = descriptors().get(name)
    if found is not None:
        return frozenset(found.streamed)
    return frozenset(o for d in DESCRIPTORS for o in d.streamed)


def redundant(name: str, available: Collection[str]) -> bool:
    """A front end (:data:`DERIVERS`) every channel of which ``available`` already has: a default stack
    leaves it out."""
    derives = [o for o, _ in DECLARED[name].outputs if o in _CHANNELS] if name in DERIVERS else []
    return bool(derives) and all(o in available for o in derives)


@dataclass(frozen=True)
class Feed:
    """How a source's channels feed one registered estimator (:func:`feeds`)."""

    missing: tuple[str, ...]  #: required channels nothing provides: it cannot run (empty: it can)
    #: each required channel the source lacks but estimators before it derive, with those estimators
    #: (any one of them feeds it): a stack without them cannot run it
    derived: dict[str, tuple[str, ...]]


class MissingChannels(ValueError):
    """An estimator asked for whose required channels the source does not send; the message names them."""


def _provided(channels: Collection[str] | None) -> set[str] | None:
    """The channels a source provides: those it sends, plus the velocity of every angle it sends (the frame
    estimator differentiates it). None: unknown (a live device), anything goes."""
    if channels is None:
        return None
    out = set(channels)
    out.update(vel for angle, vel in ANGLE_CHANNELS.items() if angle in out)
    return out


def resolve(names: Sequence[str] | None, channels: Collection[str] | None, ctx: StackContext) -> list[Estimator]:
    """Build a session's stack.

    Args:
        names: the estimators asked for (run in :data:`ESTIMATORS` order), or None for every one the
            source's channels allow but the :data:`OPT_IN` ones.
        channels: the channels the source sends (``SensorFrame`` field names), None when unknown.
        ctx: what the estimators are built from.

    Raises:
        ValueError: an unknown or repeated name.
        KeyError: an estimator declares a channel that is not in :data:`~gaitscope.sessions.schema.CHANNELS`.
        MissingChannels: a named estimator whose required channels the source lacks, or that the
            model or subject cannot build (:class:`Unavailable`: its reason).
    """
    if names is not None:
        unknown = [n for n in names if n not in ESTIMATORS]
        if unknown:
            raise ValueError(f"unknown estimator {', '.join(unknown)}; gaitscope has {', '.join(ESTIMATORS)}")
        if len(set(names)) != len(names):
            raise ValueError(f"an estimator is named twice in {list(names)}")
    available = _provided(channels)
    stack: list[Estimator] = []
    missing: list[str] = []
    cannot: list[str] = []
    for name, make in ESTIMATORS.items():
        if (names is not None and name not in names) or (names is None and name in OPT_IN):
            continue
        try:
            est = make(ctx)
        except Unavailable as e:
            if names is not None:
                cannot.append(f"{name}: {e}")
            continue
        lacking = [] if available is None else _lacking(est, available)
        if lacking:
            if names is not None:
                missing.append(f"{name} needs {', '.join(lacking)}")
            continue
        if names is None and available is not None and redundant(name, available):
            continue  # the source sends all it would derive already
        stack.append(est)
        if available is not None:
            available.update(n for n in output_names(est) if n in _CHANNELS)
    if missing:
        raise MissingChannels(f"the source does not send what the stack needs: {'; '.join(missing)}")
    if cannot:
        raise MissingChannels(f"the session cannot run {'; '.join(cannot)}")
    if not stack:
        raise MissingChannels(
            f"the source's channels ({', '.join(sorted(channels or ())) or 'none'}) feed no estimator"
        )
    return stack


def _lacking(est: Estimator, available: Collection[str]) -> list[str]:
    """:meth:`Declared.lacking` of a built estimator (one not registered: its required inputs)."""
    declared = DECLARED.get(est.name)
    if declared is None or declared.inputs != est.inputs:
        return missing_channels(est.inputs, available)
    return declared.lacking(available)


def choose_primary(wanted: str, stack: Sequence[Estimator]) -> str:
    """``wanted`` if the stack has it, else (a registered estimator the source's channels left out, or one
    a review re-run of a subset does not run) the stack's first estimator with a phase.

    Raises:
        ValueError: ``wanted`` is neither registered nor in the stack, or estimates no phase; or no
            estimator of the stack estimates a phase.
    """
    names = [e.name for e in stack]
    phased = [e.name for e in stack if "phase" in output_names(e)]
    if wanted in phased:
        return wanted
    if wanted in names:
        raise ValueError(f"{wanted} estimates no phase, so it cannot drive the torque")
    if wanted not in names and wanted not in ESTIMATORS:
        raise ValueError(f"unknown estimator {wanted}; gaitscope has {', '.join(ESTIMATORS)}")
    if not phased:
        raise ValueError(f"no estimator of the stack ({', '.join(names)}) estimates a phase")
    return phased[0]


def build_stack(
    ctx: StackContext,
    *,
    names: Sequence[str] | None,
    channels: Collection[str] | None,
    primary: str,
    torque_gain: float,
    max_torque: float,
    blend_s: float = PRIMARY_BLEND_S,
    extra: Sequence[Estimator] = (),
) -> EstimatorStack:
    """:func:`resolve` the stack (plus ``extra`` estimators, run last: test doubles, experiments) and wrap
    it in an :class:`EstimatorStack` whose primary is ``primary``, else :func:`choose_primary`'s pick."""
    stack = [*resolve(names, channels, ctx), *extra]
    out = EstimatorStack(
        stack,
        ctx.model.torque,
        ctx.leg_length,
        ctx.mass_kg,
        primary=choose_primary(primary, stack),
        torque_gain=torque_gain,
        max_torque=max_torque,
        blend_s=blend_s,
        labels={d.name: d.label for d in DESCRIPTORS},
    )
    out.requested = primary
    if out.primary != primary:
        shown = ", ".join(out.labels.values())
        follows = "none" if out.primary is None else out.labels[out.primary]
        asked = DECLARED[primary].label if primary in DECLARED else primary
        out._pending.append(f"primary {asked} is not in the stack ({shown}): the torque follows {follows}")
    return out


def feeds(channels: Collection[str], among: Collection[str] | None = None) -> dict[str, Feed]:
    """How a source sending ``channels`` feeds each registered estimator (by name, in :data:`ESTIMATORS`
    order), reckoned from :data:`DECLARED` as :func:`resolve` would run the whole registry, or only the
    estimators ``among`` (a stack asked for by name): a channel an estimator derives (``heel_strike``:
    ``hs_detector``, ``phase_ekf``) feeds those after it."""
    available = _provided(channels)
    assert available is not None
    source = set(available)
    derived: dict[str, list[str]] = {}  # channel -> the estimators that derive it
    out: dict[str, Feed] = {}
    for name, d in DECLARED.items():
        if among is not None and name not in among:
            continue
        lacking = d.lacking(available)
        needed = (*d.inputs, *(c for c in d.inputs_any if c in available))
        out[name] = Feed(tuple(lacking), {c: tuple(derived[c]) for c in needed if c not in source and c in derived})
        if not lacking:
            for o, _ in d.outputs:
                if o in _CHANNELS:
                    available.add(o)
                    derived.setdefault(o, []).append(name)
    return out


def channels_of(frames: Iterable[SensorFrame]) -> set[str]:
    """The channels (of :data:`~gaitscope.sessions.schema.CHANNELS`) a log's frames send, for :func:`resolve`."""
    found: set[str] = set()
    for frame in frames:
        found.update(n for n in CHANNELS if n not in found and getattr(frame, n) is not None)
    return found
