"""Seed 003's GP-EKF (:class:`~gaitscope.estimators.gp_ekf.GPEKF`) as a stack estimator, with its torque control
surface and its default models.

``gp_ekf`` in a session's stack. Inputs: the joint encoders ``hip_angle_deg``, ``knee_angle_deg``,
``ankle_angle_deg`` (what a simulated device sends, ``gaitscope.sessions.synth.sensors.device_channels``); optional
``heel_strike`` (used when given) and ``foot_angle_deg`` / ``foot_vel_dps`` (heel strikes detected with
:class:`~gaitscope.estimators.detector.HeelStrikeDetector` when ``heel_strike`` is NaN; the foot velocity is the
differentiated foot angle when not sent).

Joint velocities are differentiated inside: a backward difference low-passed by a first-order filter
(``velocity_cutoff_hz``, 20 Hz: an 8 ms lag, and the 14-bit encoders' 0.022 deg steps, 4.4 deg/s of
difference at 200 Hz, shrink to about 1 deg/s). An angle that is NaN, infinite or beyond +-180 deg is missing
(the filter holds its predictions, leaving that channel out) and restarts its differentiator; a velocity
beyond +-4000 deg/s is missing for that sample.

Outputs: ``phase`` is the STANCE phase (0 at heel strike, 1 at toe-off, held at 1 in swing and 0 before
the first heel strike), named ``phase`` so that the session's plots show it; ``phase_rate`` (1/s);
``in_stance``, ``heel_strike``, ``toe_off`` (1.0 / 0.0); ``torque_Nm``, the control surface's command in
stance (0 in swing); ``standing`` (0..1): in stance ``clip((hi - phidot) / (hi - lo), 0, 1)`` with ``(lo,
hi) = standing_rate`` (0.05, 0.3 /s: stances of 3-20 s are not walking), out of stance 1 after
``standing_timeout_s`` without a heel strike, and beyond seed 003 a hold when still: every joint velocity
present below ``still_dps`` (15 deg/s) for ``still_s`` (0.3 s) sets the rate to 0 (the angles alone then
place the phase on the standing posture's) and ramps ``standing`` to 1 over ``still_ramp_s``; walking on
restores the rate from before the hold (the paper's stiff filter otherwise runs on for a second after a
sudden stop, which as the primary is push-off torque on a walker who has stopped); ``model_version`` (the
installed models' version, 0 the population model); ``fault`` (:data:`~gaitscope.estimators.protocol.FAULTS`: 1
restarted after a gap, 2 the state was not finite and was reset); ``time_phase``, seed 003's time-based
baseline ``t_n / T_(n-1)`` (at most 1). ``state`` and ``covariance`` are the EKF's ``x = [phi, phidot]``
and ``P``.

The session layer drives retraining through :meth:`GPEKFEstimator.take_window`, :meth:`~GPEKFEstimator.offer`,
``frozen``, :meth:`~GPEKFEstimator.rollback` and :attr:`~GPEKFEstimator.installed` (see
:class:`~gaitscope.estimators.gp_ekf.GPEKF`).

Default models: :func:`build_default` fits the population observation models and the control surface to
cohort columns (:func:`cohort_stances`); :func:`default_arrays` / :func:`load_default` turn them into plain
arrays for an ``.npz`` and back.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Final

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from gaitscope.estimators import channels
from gaitscope.estimators.descriptor import Descriptor, Tunable, out
from gaitscope.estimators.detector import DetectorConfig, HeelStrikeDetector
from gaitscope.estimators.gp import FitOptions, SparseGP, fit_sparse_gp, rbf_mean_2d
from gaitscope.estimators.gp_ekf import DIVERGED, GPEKF, HEEL_STRIKE, TOE_OFF, GPEKFConfig, Installed, Offer
from gaitscope.estimators.gp_models import GPModelSet, TrainingWindow, fit_models
from gaitscope.estimators.protocol import HEEL_STRIKE as HS_CHANNEL
from gaitscope.estimators.protocol import MAX_GAP_S, Output, check_params, elapsed

__all__ = [
    "COHORT_COLUMNS",
    "DESCRIPTOR",
    "ControlSurface",
    "EstimatorConfig",
    "GPEKFEstimator",
    "build_default",
    "cohort_stances",
    "default_arrays",
    "fit_control_surface",
    "load_default",
]

Array = NDArray[np.float64]
#: Cohort (LocoHub) columns :func:`cohort_stances` reads.
COHORT_COLUMNS: Final = (
    "time_s",
    "phase_ipsi",
    "toe_off_ipsi",
    "hip_flexion_angle_ipsi_rad",
    "knee_flexion_angle_ipsi_rad",
    "ankle_dorsiflexion_angle_ipsi_rad",
    "ankle_dorsiflexion_moment_ipsi_Nm",
    "subject_metadata",
)
#: Bounds (deg, deg/s; symmetric about 0) of the angles it reads and of their velocities, from the channel
#: table: a value beyond them (or non-finite) is missing. The joint velocities it derives have no channel of
#: their own and take the segment rate's bound.
_ANGLE_LIMIT: Final = channels.symmetric_bound("hip_angle_deg", "knee_angle_deg", "ankle_angle_deg", "foot_angle_deg")
_VELOCITY_LIMIT: Final = channels.symmetric_bound("foot_vel_dps")
_INPUTS: Final = ("hip_angle_deg", "knee_angle_deg", "ankle_angle_deg")
_OPTIONAL: Final = (HS_CHANNEL, "foot_angle_deg", "foot_vel_dps")
#: Where :meth:`GPEKFEstimator.step` finds each channel in ``z`` (its inputs, then its optional inputs).
_HIP, _KNEE, _ANKLE, _HS, _FOOT, _FOOT_VEL = channels.positions(
    (*_INPUTS, *_OPTIONAL), "hip_angle_deg", "knee_angle_deg", "ankle_angle_deg", HS_CHANNEL, "foot_angle_deg",
    "foot_vel_dps",
)  # fmt: skip
_GAP, _DIVERGED = 1.0, 2.0  # FAULTS.index("gap"), FAULTS.index("diverged")


def _stride_mass(metadata: NDArray[np.object_]) -> Array:
    cache: dict[str, float] = {}
    for text in set(map(str, metadata)):
        fields = dict(item.split(":", 1) for item in text.split(","))
        cache[text] = float(fields["mass_kg"])
    return np.array([cache[str(m)] for m in metadata])


def cohort_stances(columns: Mapping[str, ArrayLike], index: int = 0) -> TrainingWindow:
    """The stances of a LocoHub-style table (the virtual cohort's), labelled as the filter labels its own.

    ``columns``: :data:`COHORT_COLUMNS` by name (e.g. ``{c: frame[c].to_numpy() for c in COHORT_COLUMNS}``
    of ``gaitscope.sessions.synth.cohort.generate_cohort``); angles in radians, the ankle moment in N m (dorsiflexor
    positive), the mass from ``subject_metadata`` (``mass_kg:..``). A stride starts where ``phase_ipsi`` is
    0; its stance runs to its ``toe_off_ipsi`` sample. Velocities are ``np.gradient`` of the angles within
    each stride; ``moment`` is the plantarflexor moment per kg (``-moment / mass``).
    """
    c = {k: np.asarray(columns[k]) for k in COHORT_COLUMNS}
    t = c["time_s"].astype(np.float64)
    starts = np.flatnonzero(c["phase_ipsi"].astype(np.float64) == 0.0)
    ends = np.append(starts[1:], t.size)
    toe = c["toe_off_ipsi"].astype(np.float64) > 0.5
    deg = np.degrees(np.stack([c[k].astype(np.float64) for k in COHORT_COLUMNS[3:6]], axis=1))
    moment = -c["ankle_dorsiflexion_moment_ipsi_Nm"].astype(np.float64) / _stride_mass(c["subject_metadata"])
    rows, labels, rates, vels, steps = [], [], [], [], []
    for n, (a, b) in enumerate(zip(starts, ends, strict=True)):
        hits = np.flatnonzero(toe[a:b])
        if hits.size == 0 or hits[0] < 2:
            continue
        j = a + int(hits[0])
        T = t[j] - t[a]
        r = np.arange(a, j + 1)
        rows.append(r)
        labels.append((t[r] - t[a]) / T)
        rates.append(np.full(r.size, 1.0 / T))
        vels.append(np.gradient(deg[a:b], t[a:b], axis=0)[: r.size])
        steps.append(np.full(r.size, n, dtype=np.int64))
    if not rows:
        raise ValueError("no stride with a toe-off in the table")
    r = np.concatenate(rows)
    return TrainingWindow(
        index=index,
        t=t[r],
        step=np.concatenate(steps),
        phase=np.concatenate(labels),
        phase_rate=np.concatenate(rates),
        angle=deg[r],
        velocity=np.concatenate(vels),
        moment=moment[r],
    )


@dataclass(frozen=True, eq=False)
class ControlSurface:
    """Seed 003's feedforward-torque control surface (II-B) for the ankle: a 2-D sparse GP of the
    plantarflexor moment (N m/kg) over (phase, phase rate), 0 at phase rate 0 (standing).

    The applied torque scales it as :class:`gaitscope.estimators.torque.TorqueProfile` scales its model:
    ``clip(scale * mass * surface, 0, max_torque)`` (``scale`` 1/5, plantarflexion only).
    """

    gp: SparseGP
    scale: float = 0.2

    def __post_init__(self) -> None:
        if self.gp.input_dim != 2:
            raise ValueError("a control surface is a GP of (phase, phase rate)")

    @functools.cached_property
    def _packed(self) -> tuple[Array, Array, Array]:
        return np.ascontiguousarray(self.gp.Z), 1.0 / self.gp.lengthscale**2, np.ascontiguousarray(self.gp.alpha)

    def biological(self, phase: ArrayLike, phase_rate: ArrayLike) -> Array:
        """The fitted moment per kg at arrays of states."""
        p, r = np.broadcast_arrays(np.asarray(phase, dtype=np.float64), np.asarray(phase_rate, dtype=np.float64))
        return self.gp.mean(np.stack([p.reshape(-1), r.reshape(-1)], axis=1)).reshape(p.shape)

    def torque_at(self, phase: float, phase_rate: float, mass_kg: float, max_torque: float) -> float:
        """The command (N m) at one state (compiled); 0 for a non-finite state or result."""
        Z, il2, a = self._packed
        tau = self.scale * mass_kg * rbf_mean_2d(phase, phase_rate, Z, il2, a, self.gp.offset)
        return min(max(tau, 0.0), max_torque) if math.isfinite(tau) else 0.0


def fit_control_surface(
    data: TrainingWindow,
    options: FitOptions | None = None,
    grid: tuple[int, int] = (21, 6),
    scale: float = 0.2,
    max_points: int = 2000,
) -> ControlSurface:
    """Fit the torque surface to stances with a ``moment`` (seed 003 II-B), with the paper's virtual data:
    on a ``grid`` over ``phi in [0, 1]`` and ``phidot in [0, min phidot)``, the average trajectory of the
    slowest stances (rates within 10 % of the slowest) scaled linearly to 0 at ``phidot = 0``. The real
    samples are thinned evenly to ``max_points``.

    Default options: 100 inducing points (II-B) at training inputs, not optimized (as for the observation
    models, :class:`~gaitscope.estimators.gp.FitOptions`).
    """
    if data.moment is None:
        raise ValueError("the stances carry no moment")
    options = options or FitOptions(n_inducing=100, max_points=None)
    lo = float(data.phase_rate.min())
    slow = data.phase_rate <= 1.1 * lo
    phi = np.linspace(0.0, 1.0, grid[0])
    bins = np.clip(np.round(data.phase[slow] * (grid[0] - 1)).astype(np.int64), 0, grid[0] - 1)
    counts = np.bincount(bins, minlength=grid[0])
    sums = np.bincount(bins, weights=data.moment[slow], minlength=grid[0])
    seen = counts > 0
    mean = np.interp(phi, phi[seen], sums[seen] / counts[seen])  # the slowest stances' average trajectory
    frac = np.arange(grid[1]) / grid[1]
    vx = np.stack(np.meshgrid(phi, lo * frac, indexing="ij"), axis=-1).reshape(-1, 2)
    vy = (mean[:, None] * frac[None, :]).reshape(-1)
    X = np.stack([data.phase, data.phase_rate], axis=1)
    y = data.moment
    if X.shape[0] > max_points:
        keep = np.unique(np.round(np.linspace(0, X.shape[0] - 1, max_points)).astype(np.int64))
        X, y = X[keep], y[keep]
    return ControlSurface(fit_sparse_gp(np.concatenate([X, vx]), np.concatenate([y, vy]), options), scale)


def build_default(
    columns: Mapping[str, ArrayLike], options: FitOptions | None = None, surface: FitOptions | None = None
) -> tuple[GPModelSet, ControlSurface]:
    """The population observation models (version 0) and the control surface, fitted to cohort columns
    (:func:`cohort_stances`). Seconds: call it offline and keep :func:`default_arrays` in an ``.npz``."""
    data = cohort_stances(columns)
    return fit_models(data, options), fit_control_surface(data, surface)


def default_arrays(models: GPModelSet, surface: ControlSurface) -> dict[str, Array]:
    """Plain arrays of a model set and a surface, for ``np.savez`` (:func:`load_default` reads them)."""
    out = {f"models.{k}": v for k, v in models.to_arrays().items()}
    out.update({f"surface.{k}": v for k, v in surface.gp.to_arrays().items()})
    out["surface.scale"] = np.array([surface.scale])
    return out


def load_default(arrays: Mapping[str, Array]) -> tuple[GPModelSet, ControlSurface]:
    """The inverse of :func:`default_arrays` (e.g. of ``dict(np.load(path))``)."""
    models = GPModelSet.from_arrays({k[7:]: v for k, v in arrays.items() if k.startswith("models.")})
    gp = SparseGP.from_arrays(
        {k[8:]: v for k, v in arrays.items() if k.startswith("surface.") and k != "surface.scale"}
    )
    return models, ControlSurface(gp, float(np.asarray(arrays["surface.scale"]).reshape(-1)[0]))


# --- the stack estimator ------------------------------------------------------------------------------
@njit(cache=True)
def _front(raw: Array, dt: float, tau: float, last: Array, vel: Array, z: Array, foot: Array) -> None:
    """Angles and filtered velocities of hip, knee, ankle (into ``z`` (6,)) and the foot (``foot`` (2,))
    from ``raw`` = hip, knee, ankle, foot angle (deg); ``last``, ``vel`` (4,) are the differentiators'
    state; ``dt`` 0 on a first sample (no velocity yet)."""
    alpha = dt / (tau + dt) if dt > 0 else 0.0
    for i in range(4):
        a = raw[i]
        if not (math.isfinite(a) and abs(a) <= _ANGLE_LIMIT):
            last[i] = vel[i] = np.nan
            a = np.nan
        else:
            if dt > 0 and math.isfinite(last[i]):
                d = (a - last[i]) / dt
                vel[i] = d if math.isnan(vel[i]) else vel[i] + alpha * (d - vel[i])
            last[i] = a
        v = vel[i] if abs(vel[i]) <= _VELOCITY_LIMIT else np.nan
        if i < 3:
            z[i], z[3 + i] = a, v
        else:
            foot[0], foot[1] = a, v


@dataclass(frozen=True)
class EstimatorConfig:
    """Settings of :class:`GPEKFEstimator` around the filter (module docstring).

    Attributes:
        velocity_cutoff_hz: cutoff of the first-order low-pass on the differentiated angles.
        standing_rate: ``(lo, hi)`` phase rates (1/s): ``standing`` is 1 at or below lo, 0 at or above hi.
        standing_timeout_s: out of stance, ``standing`` is 1 this long after the last heel strike.
        max_torque: bound of ``torque_Nm`` (N m).
        still_dps, still_s, still_ramp_s: the hold when still (beyond seed 003, module docstring): every
            joint velocity present below ``still_dps`` for ``still_s`` holds the filter and ramps
            ``standing`` to 1 over ``still_ramp_s``; ``still_s`` 0 turns it off (the filter as published).
    """

    velocity_cutoff_hz: float = 20.0
    standing_rate: tuple[float, float] = (0.05, 0.3)
    standing_timeout_s: float = 2.0
    max_torque: float = 30.0
    still_dps: float = 15.0
    still_s: float = 0.3
    still_ramp_s: float = 0.2

    def __post_init__(self) -> None:
        lo, hi = self.standing_rate
        if not (self.velocity_cutoff_hz > 0 and 0 <= lo < hi and self.standing_timeout_s > 0):
            raise ValueError(f"positive cutoff and timeout, 0 <= standing_rate[0] < [1]: {self}")


class GPEKFEstimator:
    """Seed 003's GP-EKF with its control surface behind the stack interface (``gp_ekf``).

    Args:
        models: the first observation models (the population model, :func:`build_default`).
        surface: the torque control surface.
        mass_kg: the user's mass (the surface is per kg).
        config: the filter's tuning and choices.
        settings: the estimator's own (velocity filter, standing, torque bound).
        detector: heel-strike detection from the foot when ``heel_strike`` is not given.

    Attributes:
        filter: the :class:`~gaitscope.estimators.gp_ekf.GPEKF` it runs.
    """

    name = "gp_ekf"
    inputs: tuple[str, ...] = _INPUTS
    optional_inputs: tuple[str, ...] = _OPTIONAL
    outputs: tuple[Output, ...] = (
        ("phase", "1"),
        ("phase_rate", "1/s"),
        ("in_stance", "bool"),
        (HS_CHANNEL, "bool"),
        ("toe_off", "bool"),
        ("torque_Nm", "N m"),
        ("standing", "1"),
        ("model_version", "code"),
        ("fault", "code"),
        ("time_phase", "1"),
    )
    tunables: tuple[str, ...] = ("measurement_noise_scale", "torque_scale")

    def __init__(
        self,
        models: GPModelSet,
        surface: ControlSurface,
        mass_kg: float,
        config: GPEKFConfig | None = None,
        settings: EstimatorConfig | None = None,
        detector: DetectorConfig | None = None,
        max_gap_s: float = MAX_GAP_S,
    ):
        if not mass_kg > 0:
            raise ValueError(f"mass_kg must be positive, got {mass_kg}")
        self.filter = GPEKF(models, config)
        self.surface = surface
        self.mass_kg = float(mass_kg)
        self.settings = settings or EstimatorConfig()
        self.detector = HeelStrikeDetector(detector)
        self.max_gap_s = max_gap_s
        self._tau = 1.0 / (2.0 * math.pi * self.settings.velocity_cutoff_hz)
        self._raw = np.zeros(4)
        self._last = np.full(4, np.nan)
        self._vel = np.full(4, np.nan)
        self._z = np.zeros(6)
        self._foot = np.zeros(2)
        self._out = np.zeros(len(self.outputs))
        self._t: float | None = None
        self._last_hs = -math.inf
        self._t0 = math.nan
        self._still_since = math.nan  # when every joint velocity last fell below still_dps (NaN: moving)
        self._held: tuple[float, float] | None = None  # the filter's phase and rate when the hold began

    def reset(self) -> None:
        """The initial models and state (tuning kept; retrained versions dropped)."""
        self.filter.reset()
        self.detector.reset()
        self._last[:] = self._vel[:] = np.nan
        self._t, self._last_hs, self._t0 = None, -math.inf, math.nan
        self._still_since, self._held = math.nan, None

    def retune(self, **params: float) -> None:
        """``measurement_noise_scale`` (x the filter's ``R``) and ``torque_scale`` (the surface's fraction
        of the biological moment)."""
        check_params(self, params)
        if "measurement_noise_scale" in params:
            if not params["measurement_noise_scale"] > 0:
                raise ValueError("measurement_noise_scale must be positive")
            self.filter.config = replace(self.filter.config, measurement_noise_scale=params["measurement_noise_scale"])
        if "torque_scale" in params:
            if not 0 <= params["torque_scale"] <= 1:
                raise ValueError("torque_scale must be in [0, 1]")
            self.surface = replace(self.surface, scale=params["torque_scale"])

    @property
    def state(self) -> Array:
        return self.filter.x

    @property
    def covariance(self) -> Array:
        return self.filter.P

    def _still(self, t: float, strike: bool) -> float:
        """The hold when still: 0 moving, ramping to 1 over ``still_ramp_s`` once every joint velocity
        present has been below ``still_dps`` for ``still_s`` (none present: moving). Records the filter's
        phase and rate when the hold begins; a heel strike or any velocity above it ends the hold."""
        s = self.settings
        v = self._z[3:6]
        present = v[np.isfinite(v)]
        if s.still_s <= 0 or strike or not len(present) or np.abs(present).max() >= s.still_dps:
            if self._held is not None and self.filter.in_stance:  # walking on: at the rate before the hold
                self.filter.x[1] = self._held[1]
            self._still_since, self._held = math.nan, None
            return 0.0
        if math.isnan(self._still_since):
            self._still_since = t
        held_for = t - self._still_since - s.still_s
        if held_for < 0:
            return 0.0
        if self._held is None:
            self._held = (float(self.filter.x[0]), float(self.filter.x[1]))
        return min(1.0, held_for / s.still_ramp_s) if s.still_ramp_s > 0 else 1.0

    # retraining, for the session layer -----------------------------------------------------------------
    def take_window(self) -> TrainingWindow | None:
        """:meth:`GPEKF.take_window`: fit it with :func:`~estimators.gp_models.fit_models`, then :meth:`offer`."""
        return self.filter.take_window()

    def offer(self, models: GPModelSet) -> Offer:
        return self.filter.offer(models)

    def rollback(self, version: int) -> str:
        return self.filter.rollback(version)

    @property
    def frozen(self) -> bool:
        return self.filter.frozen

    @frozen.setter
    def frozen(self, value: bool) -> None:
        self.filter.frozen = bool(value)

    @property
    def installed(self) -> tuple[Installed, ...]:
        return self.filter.installed

    @property
    def model_version(self) -> int:
        return self.filter.models.version

    # streaming -------------------------------------------------------------------------------------------
    def step(self, t: float, z: NDArray[np.float64]) -> NDArray[np.float64]:
        """``z``: hip, knee, ankle angle (deg), heel strike (1/0/NaN), foot angle (deg), foot velocity
        (deg/s)."""
        dt, restart = elapsed(self._t, t, self.max_gap_s)
        if self._t is None:
            self._t0 = t
        self._t = t
        f, s = self.filter, self.settings
        fault = 0.0
        if restart:
            f.restart()
            self.detector.reset()
            self._last[:] = self._vel[:] = np.nan
            fault = _GAP
        raw = self._raw
        raw[0], raw[1], raw[2], raw[3] = z[_HIP], z[_KNEE], z[_ANKLE], z[_FOOT]
        _front(raw, dt, self._tau, self._last, self._vel, self._z, self._foot)
        hs = float(z[_HS])
        if hs == hs:
            strike = hs > 0.5
        else:
            foot, foot_vel = self._foot[0], float(z[_FOOT_VEL])
            if not (math.isfinite(foot_vel) and abs(foot_vel) <= _VELOCITY_LIMIT):
                foot_vel = self._foot[1]
            strike = foot == foot and foot_vel == foot_vel and self.detector.detect(t, dt, foot, foot_vel)
        if strike:
            self._last_hs = t
        still = self._still(t, strike)
        event = f.step(t, dt, self._z, strike)
        if still > 0.0 and f.in_stance:  # held: rate 0, the angles alone place the phase (the posture's)
            f.x[1] = 0.0
        if event & DIVERGED:
            fault = _DIVERGED
        phi, rate = float(f.x[0]), float(f.x[1])
        if f.in_stance:
            lo, hi = s.standing_rate
            standing = max(min(max((hi - rate) / (hi - lo), 0.0), 1.0), still)
            torque = self.surface.torque_at(phi, rate, self.mass_kg, s.max_torque)
            tb = min((t - f.stance_start) * f.reset_rate, 1.0)
        else:
            since = t - (self._t0 if self._last_hs == -math.inf else self._last_hs)
            standing = max(1.0 if since > s.standing_timeout_s else 0.0, still)
            torque = 0.0
            phi = 0.0 if math.isnan(f.stance_start) else 1.0
            tb = phi
        out = self._out
        out[0], out[1], out[2], out[3], out[4] = phi, rate, f.in_stance, event & HEEL_STRIKE, event & TOE_OFF > 0
        out[5], out[6], out[7], out[8], out[9] = torque, standing, f.models.version, fault, tb
        return out.copy()


#: The GP-EKF as a session and the views know it (:mod:`gaitscope.estimators.descriptor`): run only when named;
#: its phase is the STANCE phase; it learns its observation models online (the "GP-EKF model", whose
#: versions its events carry).
DESCRIPTOR: Final = Descriptor(
    name=GPEKFEstimator.name,
    label="GP-EKF (seed 003)",
    inputs=GPEKFEstimator.inputs,
    optional_inputs=GPEKFEstimator.optional_inputs,
    outputs=(
        out("phase", "1", "stance phase, 0 at heel strike, 1 at toe-off"),
        out("phase_rate", "1/s", "stances per second"),
        out("in_stance", "bool", "the foot is in stance"),
        out(HS_CHANNEL, "bool"),
        out("toe_off", "bool", "a toe-off on this sample"),
        out("torque_Nm", "N m", "the control surface's torque at the estimated stance phase"),
        out("standing", "1", "1 while the walker stands still"),
        out("model_version", "code", "the version of the observation models in use"),
        out("fault", "code", "a fault code (gaitscope.estimators.protocol.FAULTS)"),
        out("time_phase", "1", "the stance phase from the stance's elapsed time alone"),
    ),
    quantities={"phase": "stance_phase", "phase_rate": "stance_phase_rate"},
    tunables=(Tunable("measurement_noise_scale"), Tunable("torque_scale", 0.0, 1.0)),
    opt_in=True,
    learned_model="GP-EKF model",
    purpose="Stance phase (heel strike to toe-off) from hip, knee and ankle encoders, with models it relearns "
    "for the wearer.",
    paper="Thatte, Shah and Geyer 2019 (seed 003)",
)
