"""What an estimator is, stated once beside it: its :class:`Descriptor`.

Each estimator module states its descriptor next to its class (a ``DESCRIPTOR`` constant, or a function of
what varies, e.g. an IMU front end's segment): its machine name and its name on screen, the channels it
reads, its outputs with their units and meanings, which outputs are gait-state quantities (:data:`QUANTITIES`),
what it lets a session tune and within which bounds, which outputs a view plots, what it is for and the paper
it implements, and the roles a session or a view gives it (run only when named, a front end that derives
channels, a model it learns online, a gait fingerprint's variant). The session level
(``gaitscope.sessions.registry``) attaches how a session builds it (:meth:`Descriptor.built_by`: a callable of
the session's context) and derives everything else from the list of descriptors: the registry's tables, the
browser's ``wire.js``, the views. Pure data: no I/O.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any, Final, Literal

from gaitscope.estimators.channels import CHANNELS
from gaitscope.estimators.protocol import Estimator, Output

__all__ = [
    "FINGERPRINT_ROLES",
    "QUANTITIES",
    "QUANTITY_NAMES",
    "Descriptor",
    "OutputSpec",
    "PlotHint",
    "Tunable",
    "out",
]

#: The gait-state quantities an output may estimate (:attr:`Descriptor.quantities`). ``phase`` is the gait
#: cycle's (0 at heel strike, 1 at the next), ``stance_phase`` the stance's (0 at heel strike, 1 at toe-off):
#: a view keeps a stance phase off a gait-phase plot. Rates in cycles (or stances) per second, stride length
#: in m, incline in deg, speeds in m/s.
QUANTITIES: Final = (
    "phase",
    "phase_rate",
    "stance_phase",
    "stance_phase_rate",
    "stride_length",
    "incline",
    "speed",
    "desired_speed",
    "knee_angle",
)
#: Each quantity's name on screen and its unit as people write it (a phase is shown in % of its cycle): the
#: one statement of them, which the views, the events and the reports read (the browser from ``wire.js``).
QUANTITY_NAMES: Final[dict[str, tuple[str, str]]] = {
    "phase": ("Gait phase", "%"),
    "phase_rate": ("Phase rate", "1/s"),
    "stance_phase": ("Stance phase", "%"),
    "stance_phase_rate": ("Stance-phase rate", "1/s"),
    "stride_length": ("Stride length", "m"),
    "incline": ("Incline", "deg"),
    "speed": ("Speed", "m/s"),
    "desired_speed": ("Desired speed", "m/s"),
    "knee_angle": ("Knee angle", "deg"),
}
#: The variants of a gait-fingerprint filter (seed 004, :attr:`Descriptor.fingerprint`): the population's
#: average fingerprint, the subject's personalized one, one estimated online.
FINGERPRINT_ROLES: Final = ("average", "personal", "online")


@dataclass(frozen=True)
class OutputSpec:
    """One output: its name, unit (see :data:`~gaitscope.estimators.protocol.Output`) and what it means."""

    name: str
    unit: str
    meaning: str


def out(name: str, unit: str, meaning: str | None = None) -> OutputSpec:
    """An :class:`OutputSpec`; the meaning defaults to the channel table's for an output that is a channel.

    Raises:
        ValueError: no meaning given for an output that is not a channel.
    """
    if meaning is None:
        if name not in CHANNELS:
            raise ValueError(f"output {name} is not a channel: say what it means")
        meaning = CHANNELS[name].description
    return OutputSpec(name, unit, meaning)


@dataclass(frozen=True)
class Tunable:
    """A parameter ``retune`` accepts, with the bounds a session keeps it within (None: none stated)."""

    name: str
    min: float | None = None
    max: float | None = None


@dataclass(frozen=True)
class PlotHint:
    """A plot a view draws of some of the estimator's outputs, one line each."""

    key: str  #: the plot's key in a view (stable: pages and tests find the plot by it)
    title: str
    y_label: str
    outputs: tuple[str, ...]


@dataclass(frozen=True)
class Descriptor:
    """An estimator as a session and a view know it, without building it (no model needed).

    ``inputs``, ``optional_inputs`` and the outputs' ``(name, unit)`` are what the built estimator declares
    (``tests/sessions/test_registry.py`` checks it); the rest is said here only.
    """

    name: str  #: its machine name in a stack (``Estimator.name``)
    label: str  #: its name on screen
    inputs: tuple[str, ...]  #: channels it requires (``Estimator.inputs``)
    outputs: tuple[OutputSpec, ...]  #: in the order ``step`` returns them
    optional_inputs: tuple[str, ...] = ()  #: channels it uses when present
    #: of these optional inputs it needs at least one (a source with none of them cannot run it): an
    #: estimator that runs on any of several measurements (the phase EKF: a foot or a shank angle)
    inputs_any: tuple[str, ...] = ()
    #: output name -> the gait-state quantity it estimates (one of :data:`QUANTITIES`)
    quantities: Mapping[str, str] = field(default_factory=dict, hash=False)
    tunables: tuple[Tunable, ...] = ()
    plots: tuple[PlotHint, ...] = ()
    #: outputs a browser gets live besides those with a quantity and those plotted (every output is recorded)
    live: tuple[str, ...] = ()
    #: run only when a session names it (by default a session runs every estimator its source can feed)
    opt_in: bool = False
    #: a front end deriving channels a source may not send: a default stack leaves it out when the source
    #: sends every channel it derives
    derives: bool = False
    #: the name on screen of a model it learns online, when it learns one: setting events whose field is
    #: the estimator's name carry that model's versions, and the live view shows its learning card
    learned_model: str | None = None
    #: which variant of the gait-fingerprint filter it is (one of :data:`FINGERPRINT_ROLES`), if one
    fingerprint: Literal["average", "personal", "online"] | None = None
    #: what it is for, in one line a clinician choosing a session's estimators reads ("": not said)
    purpose: str = ""
    #: the paper it implements, as cited on screen (``Medrano et al., IEEE T-RO 2023 (seed 000)``); "": none
    paper: str = ""
    #: how a session builds it from the session's context (attached by the registry: :meth:`built_by`)
    factory: Callable[[Any], Estimator] | None = field(default=None, compare=False, hash=False)

    def __post_init__(self) -> None:
        if not self.label or self.label == self.name:
            raise ValueError(f"{self.name}: say its name on screen (label), not its machine name")
        names = [o.name for o in self.outputs]
        if len(set(names)) != len(names):
            raise ValueError(f"{self.name}: an output is named twice in {names}")
        for o, q in self.quantities.items():
            if o not in names:
                raise ValueError(f"{self.name}: quantity of {o}, which is not an output")
            if q not in QUANTITIES:
                raise ValueError(f"{self.name}: unknown quantity {q!r}; quantities are {', '.join(QUANTITIES)}")
        for p in self.plots:
            unknown = [o for o in p.outputs if o not in names]
            if unknown or not p.outputs:
                raise ValueError(f"{self.name}: plot {p.key} draws {list(p.outputs)}, outputs are {names}")
        if "\n" in self.purpose or "\n" in self.paper:
            raise ValueError(f"{self.name}: its purpose and paper are one line each")
        unknown = [o for o in self.live if o not in names]
        if unknown:
            raise ValueError(f"{self.name}: live outputs {unknown} are not outputs {names}")
        stray = [c for c in self.inputs_any if c not in self.optional_inputs]
        if stray:
            raise ValueError(f"{self.name}: inputs_any {stray} are not optional inputs {list(self.optional_inputs)}")
        for t in self.tunables:
            if t.min is not None and t.max is not None and not t.min <= t.max:
                raise ValueError(f"{self.name}: tunable {t.name} has min {t.min} > max {t.max}")

    @property
    def declared_outputs(self) -> tuple[Output, ...]:
        """``(name, unit)`` of every output, as ``Estimator.outputs`` declares them."""
        return tuple((o.name, o.unit) for o in self.outputs)

    @property
    def streamed(self) -> tuple[str, ...]:
        """The outputs a browser gets live, in output order: those with a quantity, those plotted and
        :attr:`live`."""
        shown = {*self.quantities, *(o for p in self.plots for o in p.outputs), *self.live}
        return tuple(o.name for o in self.outputs if o.name in shown)

    @property
    def tunable_names(self) -> tuple[str, ...]:
        """The names ``retune`` accepts, as ``Estimator.tunables`` declares them."""
        return tuple(t.name for t in self.tunables)

    def built_by(self, factory: Callable[[Any], Estimator]) -> Descriptor:
        """This descriptor with the session's way of building it."""
        return replace(self, factory=factory)

    def build(self, context: Any) -> Estimator:
        """The estimator, built from a session's context.

        Raises:
            TypeError: no factory is attached (:meth:`built_by`).
        """
        if self.factory is None:
            raise TypeError(f"{self.name} has no factory: the registry attaches one (Descriptor.built_by)")
        return self.factory(context)
