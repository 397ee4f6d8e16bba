"""Seed 001's evaluation of the buttressed Kalman filter, on the virtual cohort's speed-change walks.

``gaitscope crossval --study intent``. Protocol (seed 001 Sec. III, ``shared/reference/estimators.md``
section 4), with :mod:`gaitscope.sessions.synth.intent_walks` standing in for the Ekso trials:

- each cohort subject walks three commanded speed-ups (SU) and three slow-downs (SD), command at step 8,
  and one self-paced walk with changes at steps of its own choosing; sensors at 100 Hz with the cohort's
  noise; the filter runs on the sample stream as it does live (:class:`estimators.intent_estimator.IntentEstimator`:
  touchdown from both foot forces above 5 % of their maximum, mid-stance from the hip-angle difference);
- step ``j`` is the stretch from mid-stance ``j - 1`` to mid-stance ``j``; its touchdown's step length
  and the speed measured at its mid-stance (the centre of mass's forward velocity there) are the data;
- **sign correct**: the share of steps where the sign of the filter's intent (the change of desired speed
  over the step, the live ``intent_m_s``) equals the sign of the measured change of speed ``v_j - v_(j-1)``;
  95 % Wilson interval over steps (seed 001 cites no method; a choice);
- **detection step**: the first mid-stance at or after the one closest to the command where the live
  intent class (``intent_code``, with its dead band and confidence) has the command's sign, minus that
  command step; seed 001 counts 0 or 1 step late as a success;
- **correlation** of the desired speed after each touchdown with the speed at the next mid-stance, against
  that of the filter's speed at the touchdown, mean over trials (seed 001 reports one SU trial);
- **step-length model RMSE**: eq. 1 regressed per subject on all their commanded trials with seed 001's
  labels (``v^d_k := v_(k+1)``), in sample as the paper, and leave-one-trial-out;
- three step-length models: the paper's (its uninjured subject's kappa), the subject's own (fitted on
  their other trials) and the cohort's (fitted on the other subjects, for a new subject with no
  training); and the filter fed the centre of mass from leg kinematics
  (:func:`gaitscope.estimators.com_kinematics.com_from_legs`) instead of the measured one;
- baselines on the same steps: the sign of the last measured speed change, and the sign of the step-length
  change above a threshold (``STEP_THRESHOLD_M``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Final

import numpy as np
from scipy import stats

from gaitscope.estimators.com_kinematics import LegGeometry, com_from_legs
from gaitscope.estimators.intent import UNINJURED, BKFConfig, ButtressedKF, fit_kappa
from gaitscope.estimators.intent_episodes import DEFAULT_RULE, EpisodeRule
from gaitscope.estimators.intent_estimator import IntentEstimator
from gaitscope.sessions.offline.intent_calls import CallStudy, calls_markdown, check_confidence, run_calls
from gaitscope.sessions.synth.cohort import CohortSpec
from gaitscope.sessions.synth.intent_walks import IntentProtocol, IntentTrial, intent_trials, steady_trial

__all__ = [
    "PAPER_CORR",
    "PAPER_DETECTION",
    "PAPER_SIGN_CORRECT",
    "PAPER_STEP_RMSE_M",
    "STEP_THRESHOLD_M",
    "IntentStudy",
    "StepLog",
    "log_steps",
    "run_filter",
    "run_study",
    "step_data",
    "to_markdown",
]

#: Seed 001's figures for its uninjured subject.
PAPER_SIGN_CORRECT: Final = (0.69, 0.59, 0.78)
PAPER_DETECTION: Final = "11 of 12 trials on the command step or one later (6 of 6 uninjured)"
PAPER_CORR: Final = (0.63, -0.11)  # desired speed at TD, speed at TD, with the speed at the next MS
PAPER_STEP_RMSE_M: Final = 0.025
#: The baselines call a change only when a step is this much longer or shorter than the last, or the
#: speed changed this much over the last step (choices: about the steady stride-to-stride variation).
STEP_THRESHOLD_M: Final = 0.01
SPEED_THRESHOLD_M_S: Final = 0.02
#: Dead bands of the live class (``IntentEstimator.deadband_m_s``) whose trade-off the study reports.
DEAD_BANDS_M_S: Final = (0.01, 0.03, 0.05, 0.08)


class _LoggedKF(ButtressedKF):
    """The filter, logging each touchdown and mid-stance it takes (time set by the driver)."""

    now = 0.0

    def reset(self) -> None:
        super().reset()
        self.td: list[tuple[float, float, float, float, float]] = []  # t, step, v_x^d after, v_x at TD, current
        self.ms: list[tuple[float, float, float, bool]] = []  # t, measured v_x, v_x^d after, touched

    def touchdown(self, step_length_m: float, hip_current_a: float = math.nan) -> bool:
        vx = float(self.z[3])
        ok = super().touchdown(step_length_m, hip_current_a)
        if ok:
            self.td.append((self.now, step_length_m, self.desired_speed, vx, hip_current_a))
        return ok

    def midstance(self, com: np.ndarray) -> float:
        touched, started = self._touched, self.started
        intent = super().midstance(com)
        if started:
            self.ms.append((self.now, float(np.asarray(com)[3]), self.desired_speed, touched))
        return intent


@dataclass(frozen=True)
class StepLog:
    """One trial through the filter: per mid-stance and per touchdown.

    Attributes:
        ms_t, ms_speed, ms_desired, ms_touched: mid-stance time, measured speed, desired speed after the
            update, whether a touchdown came before it (the filter's first mid-stance is not logged).
        ms_true_speed: the true speed there (the same as ``ms_speed`` unless the filter read the centre of
            mass from leg kinematics); the changes the predictions are scored against.
        ms_intent, ms_code, ms_confidence: the live outputs there (``intent_m_s``, ``intent_code``,
            ``intent_confidence``).
        td_t, td_step, td_desired, td_speed: touchdown time, step length, desired speed after the update
            and the filter's speed there.
        td_current: the RMS hip-motor current of the swing before each touchdown (A; NaN: none sent).
        com_error: measured minus true centre of mass at each mid-stance, ``(n, 6)`` (zero when the filter
            read the measured one).
    """

    ms_t: np.ndarray
    ms_speed: np.ndarray
    ms_desired: np.ndarray
    ms_touched: np.ndarray
    ms_true_speed: np.ndarray
    ms_intent: np.ndarray
    ms_code: np.ndarray
    ms_confidence: np.ndarray
    td_t: np.ndarray
    td_step: np.ndarray
    td_desired: np.ndarray
    td_speed: np.ndarray
    td_current: np.ndarray
    com_error: np.ndarray


#: The centre-of-mass channels in :func:`com_from_legs`' order.
_COM: Final = (
    "com_forward_m", "com_lateral_m", "com_up_m", "com_forward_vel_m_s", "com_lateral_vel_m_s", "com_up_vel_m_s"
)  # fmt: skip


def _inputs(trial: IntentTrial, kinematic: bool) -> tuple[np.ndarray, np.ndarray]:
    """The estimator's input matrix over the trial (its ``inputs`` then ``optional_inputs``; contact flags
    and motor current left NaN, so touchdown comes from forces as in seed 001), and the true CoM."""
    f = trial.sensors
    names = [*IntentEstimator.inputs, *IntentEstimator.optional_inputs]
    z = np.full((len(f), len(names)), np.nan)
    for i, name in enumerate(names):
        if name in f and not name.startswith(("foot_contact", "motor_current")):
            z[:, i] = f[name].to_numpy(np.float64)
    com_idx = [names.index(n) for n in _COM]
    true = z[:, com_idx].copy()
    if kinematic:
        col = {c: f[c].to_numpy(np.float64) for c in f.columns}
        z[:, com_idx] = com_from_legs(
            LegGeometry.from_leg_length(trial.subject.leg_length_m),
            col["thigh_angle_deg"], col["shank_angle_deg"], col["thigh_vel_dps"], col["shank_vel_dps"],
            col["foot_force_N"], col["thigh_angle_contra_deg"], col["shank_angle_contra_deg"],
            col["thigh_vel_contra_dps"], col["shank_vel_contra_dps"], col["foot_force_contra_N"],
        )  # fmt: skip
    return z, true


def run_filter(
    trial: IntentTrial,
    config: BKFConfig = UNINJURED,
    kinematic: bool = False,
    episodes: EpisodeRule | None = DEFAULT_RULE,
    **options: float,
) -> StepLog:
    """Run the live estimator (with the episode rule ``episodes`` and ``options``, e.g. ``min_confidence``)
    over a trial's samples and log its events."""
    z, true = _inputs(trial, kinematic)
    t = trial.sensors["time_s"].to_numpy(np.float64)
    return log_steps(trial.subject.leg_length_m, config, t, z, true, episodes, **options)


def log_steps(
    leg_length_m: float,
    config: BKFConfig,
    t: np.ndarray,
    z: np.ndarray,
    true_com: np.ndarray | None = None,
    episodes: EpisodeRule | None = DEFAULT_RULE,
    **options: float,
) -> StepLog:
    """Run the live estimator over samples ``z`` (its ``inputs`` then ``optional_inputs``, NaN: missing) at
    times ``t`` and log its events; ``true_com`` (the six CoM channels' truth, default: as measured) is what
    ``com_error`` and ``ms_true_speed`` are against."""
    est = IntentEstimator(leg_length_m, config, episodes=episodes, **options)  # type: ignore[arg-type]
    kf = _LoggedKF(leg_length_m, config)
    est.filter = kf
    names = [*IntentEstimator.inputs, *IntentEstimator.optional_inputs]
    com = [names.index(n) for n in _COM]
    true = z[:, com] if true_com is None else true_com
    outs, errors, true_speed, n_ms = [], [], [], 0
    for i in range(len(t)):
        kf.now = float(t[i])
        out = est.step(float(t[i]), z[i])
        if len(kf.ms) > n_ms:
            n_ms = len(kf.ms)
            outs.append(out)
            errors.append(z[i, com] - true[i])
            true_speed.append(true[i, 3])
    ms = np.array(kf.ms, dtype=np.float64).reshape(-1, 4)
    td = np.array(kf.td, dtype=np.float64).reshape(-1, 5)
    o = np.array(outs, dtype=np.float64).reshape(-1, len(IntentEstimator.outputs))
    names = [n for n, _ in IntentEstimator.outputs]
    return StepLog(
        ms_t=ms[:, 0], ms_speed=ms[:, 1], ms_desired=ms[:, 2], ms_touched=ms[:, 3] > 0.5,
        ms_true_speed=np.array(true_speed, dtype=np.float64),
        ms_intent=o[:, names.index("intent_m_s")], ms_code=o[:, names.index("intent_code")],
        ms_confidence=o[:, names.index("intent_confidence")],
        td_t=td[:, 0], td_step=td[:, 1], td_desired=td[:, 2], td_speed=td[:, 3], td_current=td[:, 4],
        com_error=np.array(errors).reshape(-1, 6),
    )  # fmt: skip


def _td_before(log: StepLog) -> np.ndarray:
    """For each mid-stance, the index of the touchdown between it and the previous one (-1: none)."""
    idx = np.searchsorted(log.td_t, log.ms_t, side="right") - 1
    prev = np.r_[-np.inf, log.ms_t[:-1]]
    ok = (idx >= 0) & (log.td_t[np.maximum(idx, 0)] > prev) if len(log.td_t) else np.zeros(len(idx), bool)
    return np.where(ok, idx, -1)


def step_data(log: StepLog, current: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Steps with a touchdown and a mid-stance before them: ``(v_(j-1), v_j, l_j)`` (m/s, m/s, m), or with
    ``current`` the touchdown's RMS hip current in place of the step length (A; for eq. 14)."""
    td = _td_before(log)
    j = np.flatnonzero((td >= 0) & (np.arange(len(td)) >= 1))
    return log.ms_speed[j - 1], log.ms_speed[j], (log.td_current if current else log.td_step)[td[j]]


def _model_rmse(kappa: np.ndarray, data: tuple[np.ndarray, np.ndarray, np.ndarray], leg: float) -> np.ndarray:
    v0, v1, step = data
    return step - (kappa[0] * v0 + kappa[1] * (v1 - v0) + kappa[2] * leg)


@dataclass(frozen=True)
class Scores:
    """What seed 001 reports, for one filter or baseline over a set of trials.

    Attributes:
        sign_hits, sign_steps: steps whose predicted sign equals the measured change's, and steps.
        onset_hits, onset_steps: the same on each commanded trial's first step of change (the step after
            the command step, where the speed starts to change; what a speed-based rule cannot know yet).
        delays: detection minus command step, per commanded trial detected.
        missed: commanded trials never detected.
        steady_calls, steady_steps: calls (of either sign) on the steps before the command, and steps.
        corr_desired, corr_speed: mean over trials (filters only).
    """

    sign_hits: int
    sign_steps: int
    onset_hits: int = 0
    onset_steps: int = 0
    delays: list[int] = field(default_factory=list)
    missed: int = 0
    steady_calls: int = 0
    steady_steps: int = 0
    corr_desired: float = math.nan
    corr_speed: float = math.nan

    @property
    def sign_rate(self) -> tuple[float, float, float]:
        return _rate(self.sign_hits, self.sign_steps)

    @property
    def onset_rate(self) -> tuple[float, float, float]:
        return _rate(self.onset_hits, self.onset_steps)

    @property
    def on_time(self) -> int:
        return sum(1 for d in self.delays if 0 <= d <= 1)


def _rate(hits: int, n: int) -> tuple[float, float, float]:
    """Share and its 95 % Wilson interval."""
    if not n:
        return math.nan, math.nan, math.nan
    ci = stats.binomtest(hits, n).proportion_ci(0.95, method="wilson")
    return hits / n, float(ci.low), float(ci.high)


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 3 or np.std(a[ok]) == 0 or np.std(b[ok]) == 0:
        return math.nan
    return float(np.corrcoef(a[ok], b[ok])[0, 1])


#: A predictor: for a trial's log and its steps ``j`` (mid-stance indices, with ``td`` the touchdown before
#: each), the predicted sign of each step's speed change and the call it makes (0: none).
Predictor = Callable[[StepLog, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


def _filter_prediction(log: StepLog, j: np.ndarray, td: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The intent as inferred at the step's touchdown (seed 001 Fig. 6's stems): the desired speed after
    the touchdown update minus that after the previous mid-stance; the call is the live class."""
    return np.sign(log.td_desired[td[j]] - log.ms_desired[j - 1]), log.ms_code[j]


def _last_change(log: StepLog, j: np.ndarray, td: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = log.ms_speed[j - 1] - log.ms_speed[np.maximum(j - 2, 0)]
    return np.sign(d), np.where(np.abs(d) > SPEED_THRESHOLD_M_S, np.sign(d), 0.0)


def _step_change(log: StepLog, j: np.ndarray, td: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = log.td_step[td[j]] - log.td_step[td[np.maximum(j - 1, 0)]]
    return np.sign(d), np.where(np.abs(d) > STEP_THRESHOLD_M, np.sign(d), 0.0)


def score(trials: Sequence[IntentTrial], logs: Sequence[StepLog], predict: Predictor, correlate: bool) -> Scores:
    """Score a predictor on the steps every predictor has (two mid-stances and two touchdowns before)."""
    hits = steps = onset_hits = onset_steps = missed = calls = steady = 0
    delays: list[int] = []
    corr_d, corr_v = [], []
    for trial, log in zip(trials, logs, strict=True):
        td = _td_before(log)
        j = np.flatnonzero((td >= 0) & (np.arange(len(td)) >= 2) & (np.r_[-1, td[:-1]] >= 0))
        if not len(j):
            missed += int(trial.direction != 0)
            continue
        measured = np.sign(log.ms_true_speed[j] - log.ms_true_speed[j - 1])
        sign, call = predict(log, j, td)
        hits += int(np.sum(sign == measured))
        steps += len(j)
        if correlate:
            corr_d.append(_corr(log.td_desired[td[j]], log.ms_true_speed[j]))
            corr_v.append(_corr(log.td_speed[td[j]], log.ms_true_speed[j]))
        if not trial.direction:
            continue
        c = int(np.argmin(np.abs(log.ms_t - trial.command_time_s)))
        onset = j == c + 1
        onset_hits += int(np.sum(sign[onset] == trial.direction))
        onset_steps += int(onset.sum())
        before = j < c
        calls += int(np.sum(call[before] != 0))
        steady += int(before.sum())
        found = j[(j >= c) & (call == trial.direction)]
        if len(found):
            delays.append(int(found[0]) - c)
        else:
            missed += 1
    mean = (lambda x: float(np.nanmean(x)) if np.isfinite(x).any() else math.nan) if correlate else (lambda x: math.nan)
    return Scores(hits, steps, onset_hits, onset_steps, delays, missed, calls, steady, mean(corr_d), mean(corr_v))


@dataclass(frozen=True)
class IntentStudy:
    """Every row of the tables, with the protocol and the models behind them."""

    protocol: IntentProtocol
    n_subjects: int
    commanded: dict[str, Scores]
    self_paced: dict[str, Scores]
    step_rmse_in_sample_m: float
    step_rmse_held_out_m: float
    cohort_kappa: np.ndarray
    com_rmse: np.ndarray  # forward position, up position, forward velocity, up velocity at mid-stance
    #: the per-step class's dead band -> the commanded trials' scores and calls per step of the self-paced walks
    dead_bands: dict[float, tuple[Scores, float]]
    #: the live call (speed-change episodes), nested leave-one-subject-out
    calls: CallStudy | None = None


def _config(kappa: np.ndarray) -> BKFConfig:
    return replace(UNINJURED, kappa=(float(kappa[0]), float(kappa[1]), float(kappa[2])))


def run_study(
    protocol: IntentProtocol | None = None,
    spec: CohortSpec | None = None,
    steady_minutes: float = 5.0,
    call_grid: list[EpisodeRule] | None = None,
) -> IntentStudy:
    """The whole study (see the module docstring) on ``spec``'s subjects (default: the cohort's ten);
    deterministic for a given protocol. ``steady_minutes``: each subject's steady walk for the live call's
    false calls (:mod:`gaitscope.sessions.offline.intent_calls`, on ``call_grid``; 0: no such section)."""
    protocol = protocol or IntentProtocol()
    trials = intent_trials(protocol, spec)
    subjects = sorted({t.subject.code for t in trials})
    by_subject = {c: [i for i, t in enumerate(trials) if t.subject.code == c] for c in subjects}
    commanded = [i for i, t in enumerate(trials) if t.direction]
    # Step data for the regressions: from the paper-model run (the data do not depend on kappa).
    paper_logs = [run_filter(t, episodes=None) for t in trials]
    data = [step_data(log) for log in paper_logs]
    legs = [t.subject.leg_length_m for t in trials]

    def fit(idx: Sequence[int]) -> np.ndarray:
        return fit_kappa([data[i] for i in idx], [legs[i] for i in idx])

    in_sample, held_out = [], []
    subject_kappa: dict[int, np.ndarray] = {}
    cohort_kappa: dict[str, np.ndarray] = {}
    for code, idx in by_subject.items():
        own = [i for i in idx if trials[i].direction]
        k_all = fit(own)
        in_sample += [_model_rmse(k_all, data[i], legs[i]) for i in own]
        for i in idx:
            k = fit([o for o in own if o != i])
            subject_kappa[i] = k
            if i in own:
                held_out.append(_model_rmse(k, data[i], legs[i]))
        cohort_kappa[code] = fit([i for i in commanded if trials[i].subject.code != code])
    logs = {  # the class per step, as seed 001 scores it (the live call, episodes, is scored below)
        "paper": paper_logs,
        "subject": [run_filter(t, _config(subject_kappa[i]), episodes=None) for i, t in enumerate(trials)],
        "cohort": [run_filter(t, _config(cohort_kappa[t.subject.code]), episodes=None) for t in trials],
        "kinematic": [
            run_filter(t, _config(cohort_kappa[t.subject.code]), kinematic=True, episodes=None) for t in trials
        ],
    }
    self_paced = [i for i, t in enumerate(trials) if not t.direction]

    def scores(idx: list[int]) -> dict[str, Scores]:
        tr = [trials[i] for i in idx]
        out = {name: score(tr, [lg[i] for i in idx], _filter_prediction, True) for name, lg in logs.items()}
        base = [logs["cohort"][i] for i in idx]
        out["last_change"] = score(tr, base, _last_change, False)
        out["step_change"] = score(tr, base, _step_change, False)
        return out

    dead_bands = {}
    for band in DEAD_BANDS_M_S:
        lg = [run_filter(t, _config(cohort_kappa[t.subject.code]), deadband_m_s=band, episodes=None) for t in trials]
        sc = score([trials[i] for i in commanded], [lg[i] for i in commanded], _filter_prediction, False)
        per_step = [lg[i].ms_code[2:] != 0 for i in self_paced]
        dead_bands[band] = (sc, float(np.mean(np.concatenate(per_step))))
    com_err = np.vstack([lg.com_error for lg in logs["kinematic"]])[:, [0, 2, 3, 5]]
    calls: CallStudy | None = None
    if steady_minutes > 0:
        walks = [*trials]
        for subject in {t.subject.code: t.subject for t in trials}.values():
            walks.append(steady_trial(subject, 0, protocol, steady_minutes))
        configs = [_config(cohort_kappa[t.subject.code]) for t in walks]
        calls = run_calls(walks, configs, lambda t, c, r: run_filter(t, c, episodes=r), call_grid)
        raw = {  # the filter's own z-scores of the steady walks' steps (confidence_scale 1; 0: held)
            w.subject.code: run_filter(w, c, episodes=None, confidence_scale=1.0).ms_confidence
            for w, c in zip(walks, configs, strict=True)
            if w.name.startswith("ST")
        }
        calls = replace(calls, confidence=check_confidence({k: v[v > 0] for k, v in raw.items()}))
    return IntentStudy(
        protocol=protocol,
        n_subjects=len(subjects),
        commanded=scores(commanded),
        self_paced=scores(self_paced),
        step_rmse_in_sample_m=float(np.sqrt(np.mean(np.concatenate(in_sample) ** 2))),
        step_rmse_held_out_m=float(np.sqrt(np.mean(np.concatenate(held_out) ** 2))),
        cohort_kappa=fit(commanded),
        com_rmse=np.sqrt(np.nanmean(com_err**2, axis=0)),
        dead_bands=dead_bands,
        calls=calls,
    )


LABELS: Final = {
    "paper": "BKF, the paper's kappa",
    "subject": "BKF, the subject's own kappa (other trials)",
    "cohort": "BKF, the cohort's kappa (other subjects)",
    "kinematic": "BKF, cohort kappa, CoM from leg kinematics",
    "last_change": f"baseline: sign of the last speed change (call above {SPEED_THRESHOLD_M_S:g} m/s)",
    "step_change": f"baseline: sign of the step-length change (call above {100 * STEP_THRESHOLD_M:g} cm)",
}


def _pct(x: tuple[float, float, float]) -> str:
    return "-" if math.isnan(x[0]) else f"{100 * x[0]:.0f} % [{100 * x[1]:.0f}-{100 * x[2]:.0f}]"


def _num(x: float) -> str:
    return "-" if math.isnan(x) else f"{x:.2f}"


def to_markdown(study: IntentStudy) -> str:
    p = study.protocol
    cmd = study.commanded
    n_cmd = len(cmd["paper"].delays) + cmd["paper"].missed
    lines = [
        f"Seed 001 on the virtual cohort: {study.n_subjects} subjects x {p.trials_per_direction} SU + "
        f"{p.trials_per_direction} SD commanded trials ({n_cmd} in all) and one self-paced walk each; "
        f"speed-change model: step lead {p.step_lead:g}, speed time constant {p.speed_tau_steps:g} steps, "
        f"speed CV {100 * p.speed_cv:g} % (`gaitscope crossval --study intent`).",
        "",
        "| commanded trials | sign of next speed change correct [95 % CI] | at the onset step "
        "| detected on the command step or one later (missed) | calls per steady step "
        "| corr(v_d at TD, v next MS) | corr(v at TD, v next MS) |",
        "|---|---|---|---|---|---|---|",
        f"| seed 001, uninjured subject (Ekso GT) | {_pct(PAPER_SIGN_CORRECT)} | - | {PAPER_DETECTION} | - "
        f"| {PAPER_CORR[0]:.2f} | {PAPER_CORR[1]:.2f} |",
    ]
    for key, sc in cmd.items():
        steady = "-" if not sc.steady_steps else f"{sc.steady_calls / sc.steady_steps:.2f}"
        lines.append(
            f"| {LABELS[key]} | {_pct(sc.sign_rate)} | {_pct(sc.onset_rate)} | {sc.on_time} of {n_cmd} ({sc.missed}) "
            f"| {steady} | {_num(sc.corr_desired)} | {_num(sc.corr_speed)} |"
        )
    lines += [
        "",
        "| self-paced walks (changes when the walker chose) | sign correct [95 % CI] | corr(v_d at TD, v next MS) "
        "| corr(v at TD, v next MS) |",
        "|---|---|---|---|",
    ]
    for key, sc in study.self_paced.items():
        lines.append(f"| {LABELS[key]} | {_pct(sc.sign_rate)} | {_num(sc.corr_desired)} | {_num(sc.corr_speed)} |")
    delays = cmd["cohort"].delays
    hist = ", ".join(f"{d} steps: {delays.count(d)}" for d in sorted(set(delays)))
    k, r = study.cohort_kappa, study.com_rmse
    lines += [
        "",
        f"- Detection delay after the command step, cohort kappa: {hist or '-'} trials.",
        f"- Step-length model (eq. 1) RMSE: {100 * study.step_rmse_in_sample_m:.1f} cm in sample, "
        f"{100 * study.step_rmse_held_out_m:.1f} cm on a held-out trial "
        f"(seed 001: {100 * PAPER_STEP_RMSE_M:.1f} cm).",
        f"- The cohort's kappa (all subjects' commanded trials): [{k[0]:.4f}, {k[1]:.4f}, {k[2]:.4f}] "
        "(seed 001's uninjured subject: [0.3325, 0.2635, 0.3757]).",
        f"- Centre of mass from leg kinematics, RMSE at mid-stance: forward {100 * r[0]:.1f} cm, "
        f"up {100 * r[1]:.1f} cm, forward velocity {r[2]:.3f} m/s, up velocity {r[3]:.3f} m/s.",
        "",
        "A class per step (`intent_code` of earlier versions, `episodes=None`) against its dead band (cohort kappa, "
        "`min_confidence` 2): commanded changes caught on time against calls while the speed is steady. Every "
        "row calls far more often than once per 5 minutes (about 525 steps); the live call is now an episode, below.",
        "",
        "| dead band (m/s) | detected on the command step or one later (missed) | calls per steady step "
        "| calls per step, self-paced walks |",
        "|---|---|---|---|",
    ]
    for band, (sc, calls) in study.dead_bands.items():
        rate = sc.steady_calls / sc.steady_steps if sc.steady_steps else math.nan
        lines.append(f"| {band:g} | {sc.on_time} of {n_cmd} ({sc.missed}) | {rate:.2f} | {calls:.2f} |")
    if study.calls is not None:
        lines += calls_markdown(study.calls)
    return "\n".join(lines) + "\n"
