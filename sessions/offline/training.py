"""Fit gaitscope's models from a LocoHub table (the default cohort or a lab's own data).

A table is turned into :class:`StrideData`: strides of 150 phase samples each with their phase rate,
normalised stride length and incline, the measured channels and the plantarflexor moment. From it,
per-subject Gram matrices make leave-one-subject-out refits cheap (:mod:`gaitscope.estimators.gait_model`).

Protocol (seed 000 II-B, II-C4 and the authors' code):

- stride duration from the time stamps; phase rate ``1/T``; stride length ``speed x T``, normalised
  by the subject's leg length (``leg_length_m`` in ``subject_metadata``, else 0.53 x ``height_m``,
  Winter's proportion);
- heel positions high-passed across the strides of each trial in time order, then divided by leg length;
- angular velocities by differentiating the angles in time within each stride;
- ``Sigma_xsub``: residuals of every training subject against the model fitted without it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from gaitscope.estimators.basis import Array
from gaitscope.estimators.fingerprint import FingerprintMap, fit_map
from gaitscope.estimators.gait_model import (
    OUT_FOOT,
    OUT_HEEL_FORWARD,
    OUT_HEEL_UP,
    OUT_SHANK,
    SENSOR_VARIANCE,
    Gram,
    NoiseModel,
    evaluate,
    fit_outputs,
    gram,
    residual_covariance,
)
from gaitscope.estimators.highpass import HighPassFilter
from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.estimators.torque import TorqueProfile, fit_torque
from gaitscope.sessions import schema
from gaitscope.sessions.formats.locohub import parse_task_info

SAMPLES_PER_STRIDE = 150
LEG_LENGTH_PER_HEIGHT = 0.530  # Winter, Biomechanics and Motor Control of Human Movement, 4th ed., Fig. 4.1


@dataclass(frozen=True)
class StrideData:
    """Training data as strides x 150 phase samples.

    Attributes:
        subjects: subject codes, ``(n_subjects,)``.
        subject: index into ``subjects`` per stride, ``(S,)``.
        p: phase of each of the 150 samples, ``(150,)``.
        pdot, l, r: phase rate (1/s), stride length (leg lengths) and incline (deg) per stride, ``(S,)``.
        leg_length, mass: per stride (m, kg), ``(S,)``.
        z: measured channels ``(S, 150, 6)``: foot, foot velocity, shank, shank velocity (deg, deg/s),
            high-passed heel forward and heel up (m; zero when the table has no heel positions).
        outputs: which model outputs the table could train (foot, shank, heel forward, heel up).
        moment: plantarflexor moment per kg (N m/kg), ``(S, 150)``.
        thigh: thigh angle (deg), ``(S, 150)``, None when the table has none (no fingerprint map).
    """

    subjects: tuple[str, ...]
    subject: Array
    p: Array
    pdot: Array
    l: Array
    r: Array
    leg_length: Array
    mass: Array
    z: Array
    moment: Array
    speeds: tuple[float, ...]
    inclines: tuple[float, ...]
    outputs: tuple[bool, bool, bool, bool] = (True, True, True, True)
    thigh: Array | None = None

    def rows(self, subject: int) -> tuple[Array, Array, Array, Array, Array]:
        """Flattened ``(p, l, r, z, moment)`` samples of one subject."""
        m = self.subject == subject
        n = int(m.sum())
        P = np.broadcast_to(self.p, (n, SAMPLES_PER_STRIDE)).reshape(-1)
        L = np.repeat(self.l[m], SAMPLES_PER_STRIDE)
        R = np.repeat(self.r[m], SAMPLES_PER_STRIDE)
        return P, L, R, self.z[m].reshape(-1, 6), self.moment[m].reshape(-1)


def _metadata(frame: pd.DataFrame) -> dict[str, dict[str, float]]:
    out: dict[str, dict[str, float]] = {}
    for subject, text in frame.groupby(schema.SUBJECT, sort=False)[schema.SUBJECT_METADATA].first().items():
        info = parse_task_info(str(text)) if isinstance(text, str) and text else {}
        meta = {k: float(v) for k, v in info.items() if _is_number(v)}
        if "leg_length_m" not in meta:
            if "height_m" not in meta:
                raise ValueError(f"subject {subject}: subject_metadata has neither leg_length_m nor height_m")
            meta["leg_length_m"] = LEG_LENGTH_PER_HEIGHT * meta["height_m"]
        if "mass_kg" not in meta:
            raise ValueError(f"subject {subject}: subject_metadata has no mass_kg (needed for the torque model)")
        out[str(subject)] = meta
    return out


def _is_number(v: str) -> bool:
    try:
        float(v)
    except ValueError:
        return False
    return True


def stride_data(frame: pd.DataFrame) -> StrideData:
    """Arrange a LocoHub table (see :data:`gaitscope.sessions.schema.TRAINING_COLUMNS`) into strides."""
    if schema.SUBJECT_METADATA not in frame.columns:
        raise ValueError("the table has no subject_metadata column (leg length and mass are needed)")
    meta = _metadata(frame)
    keys = [schema.SUBJECT, schema.TASK_INFO, schema.STEP]
    if schema.PHASE_IPSI not in frame.columns:
        frame = to_phase_grid(frame)
    f = frame.sort_values([*keys, schema.PHASE_IPSI], kind="stable")
    sizes = f.groupby(keys, sort=False).size()
    if not (sizes == SAMPLES_PER_STRIDE).all():
        bad = sizes[sizes != SAMPLES_PER_STRIDE].index[0]
        raise ValueError(
            f"stride {bad} has {sizes[bad]} samples; phase-indexed tables have 150 per stride "
            "(leave out phase_ipsi to have time-indexed strides resampled)"
        )
    S = len(sizes)
    shape = (S, SAMPLES_PER_STRIDE)
    t = f[schema.TIME_S].to_numpy(np.float64).reshape(shape)
    p = f[schema.PHASE_IPSI].to_numpy(np.float64).reshape(shape) / 100.0
    if not np.allclose(p, p[0]):
        raise ValueError("strides must share one phase grid (phase_ipsi = i / 149 x 100)")
    T = (t[:, -1] - t[:, 0]) / (p[:, -1] - p[:, 0])
    if np.any(~(T > 0)):
        raise ValueError("a stride has non-increasing time stamps")
    info = {k: parse_task_info(k) for k in f[schema.TASK_INFO].unique()}
    task = f[schema.TASK_INFO].to_numpy()[::SAMPLES_PER_STRIDE]
    speed = np.array([float(info[k]["speed_m_s"]) for k in task])
    incline = np.array([float(info[k]["incline_deg"]) for k in task])
    subj = f[schema.SUBJECT].to_numpy()[::SAMPLES_PER_STRIDE].astype(str)
    subjects = tuple(dict.fromkeys(subj))
    leg = np.array([meta[s]["leg_length_m"] for s in subj])
    mass = np.array([meta[s]["mass_kg"] for s in subj])

    foot = np.degrees(f[schema.FOOT_ANGLE].to_numpy(np.float64).reshape(shape))
    shank = np.degrees(f[schema.SHANK_ANGLE].to_numpy(np.float64).reshape(shape))
    z = np.empty((S, SAMPLES_PER_STRIDE, 6))
    z[..., 0], z[..., 2] = foot, shank
    z[..., 1] = np.gradient(foot, axis=1) / np.gradient(t, axis=1)
    z[..., 3] = np.gradient(shank, axis=1) / np.gradient(t, axis=1)
    has_heel = all(c in f.columns for c in schema.OPTIONAL_TRAINING_COLUMNS)
    if has_heel:
        heel = np.stack([f[schema.HEEL_FORWARD].to_numpy(np.float64), f[schema.HEEL_UP].to_numpy(np.float64)], axis=1)
        z[..., 4:6] = _highpass_trials(f, heel).reshape(S, SAMPLES_PER_STRIDE, 2)
    else:
        z[..., 4:6] = 0.0  # not measured: those outputs are fitted to zero and masked at run time
    moment = -f[schema.ANKLE_MOMENT].to_numpy(np.float64).reshape(shape) / mass[:, None]
    thigh = np.degrees(f[schema.THIGH_ANGLE].to_numpy(np.float64).reshape(shape)) if schema.THIGH_ANGLE in f else None
    return StrideData(
        subjects=subjects,
        subject=np.array([subjects.index(s) for s in subj]),
        p=p[0] % 1.0,
        pdot=1.0 / T,
        l=speed * T / leg,
        r=incline,
        leg_length=leg,
        mass=mass,
        z=z,
        moment=moment,
        speeds=tuple(sorted(set(speed.tolist()))),
        inclines=tuple(sorted(set(incline.tolist()))),
        outputs=(True, True, has_heel, has_heel),
        thigh=thigh if thigh is not None and np.isfinite(thigh).all() else None,
    )


def to_phase_grid(frame: pd.DataFrame) -> pd.DataFrame:
    """A time-indexed LocoHub table (``time_s`` and ``step``, no ``phase_ipsi``) resampled to 150 samples
    per stride at phases ``i / 149``, as the phase-indexed format has them.

    Each step runs from its heel strike to the next one: its phase is linear in time from its first
    sample to the first sample of the next step of the same trial (or, for a trial's last step, one
    median sample period after its own last sample). Every numeric column is interpolated linearly in
    phase; text columns are carried. Steps with fewer than 10 samples are refused.
    """
    keys = [schema.SUBJECT, schema.TASK_INFO, schema.STEP]
    f = frame.sort_values([schema.SUBJECT, schema.TASK_INFO, schema.TIME_S], kind="stable")
    numeric = [c for c in f.columns if c not in keys and pd.api.types.is_numeric_dtype(f[c])]
    text = [c for c in f.columns if c not in keys and c not in numeric]
    grid = np.arange(SAMPLES_PER_STRIDE) / (SAMPLES_PER_STRIDE - 1)
    parts = []
    for _, trial in f.groupby([schema.SUBJECT, schema.TASK_INFO], sort=False):
        t_all = trial[schema.TIME_S].to_numpy(np.float64)
        period = float(np.median(np.diff(t_all))) if len(t_all) > 1 else 0.01
        steps = list(trial.groupby(schema.STEP, sort=False))
        for k, (step, rows) in enumerate(steps):
            if len(rows) < 10:
                raise ValueError(f"step {step} of {rows[schema.SUBJECT].iloc[0]} has {len(rows)} samples (10 needed)")
            t = rows[schema.TIME_S].to_numpy(np.float64)
            end = steps[k + 1][1][schema.TIME_S].iloc[0] if k + 1 < len(steps) else t[-1] + period
            phase = (t - t[0]) / (end - t[0])
            out = {c: np.interp(grid, phase, rows[c].to_numpy(np.float64)) for c in numeric}
            out[schema.TIME_S] = t[0] + grid * (end - t[0])
            out[schema.PHASE_IPSI] = grid * 100.0
            block = pd.DataFrame(out)
            for c in (*keys, *text):
                block[c] = rows[c].iloc[0]
            parts.append(block)
    if not parts:
        raise ValueError("the table has no strides")
    return pd.concat(parts, ignore_index=True)


def _highpass_trials(f: pd.DataFrame, heel: Array) -> Array:
    """High-pass heel positions across the strides of each (subject, task) in time order."""
    out = np.empty_like(heel)
    t = f[schema.TIME_S].to_numpy(np.float64)
    groups = f.groupby([schema.SUBJECT, schema.TASK_INFO], sort=False).indices
    for group in groups.values():
        idx = np.asarray(group)
        order = idx[np.argsort(t[idx], kind="stable")]
        tt = t[order]
        keep = np.concatenate([[True], np.diff(tt) > 0])  # boundary samples repeat between strides
        u = order[keep]
        dt = float(np.median(np.diff(t[u]))) if u.size > 1 else 0.01
        filtered = HighPassFilter(dt).filter(heel[u])
        pos = np.searchsorted(t[u], tt)  # the repeated sample takes the value of its first occurrence
        out[order] = filtered[pos]
    return out


def subject_grams(data: StrideData, order: int, torque_order: int) -> tuple[list[Gram], list[Gram]]:
    """Per-subject Grams of the gait outputs (heel in leg lengths) and of the torque target."""
    gait, torque = [], []
    for s in range(len(data.subjects)):
        P, L, R, Z, M = data.rows(s)
        leg = np.repeat(data.leg_length[data.subject == s], SAMPLES_PER_STRIDE)
        Y = np.stack([Z[:, 0], Z[:, 2], Z[:, 4] / leg, Z[:, 5] / leg], axis=1)
        gait.append(gram(P, L, R, Y, order))
        torque.append(gram(P, L, R, M[:, None], torque_order))
    return gait, torque


def residuals(data: StrideData, subject: int, coef: Array) -> tuple[Array, Array]:
    """Phases and residuals ``z - h(x_true)`` ``(n, 6)`` of one subject against ``coef``."""
    P, L, R, Z, _ = data.rows(subject)
    m = data.subject == subject
    pdot = np.repeat(data.pdot[m], SAMPLES_PER_STRIDE)
    leg = np.repeat(data.leg_length[m], SAMPLES_PER_STRIDE)
    h = evaluate(coef, P, L, R)
    hp = evaluate(coef, P, L, R, dp=1)
    pred = np.stack(
        [
            h[:, OUT_FOOT],
            pdot * hp[:, OUT_FOOT],
            h[:, OUT_SHANK],
            pdot * hp[:, OUT_SHANK],
            leg * h[:, OUT_HEEL_FORWARD],
            leg * h[:, OUT_HEEL_UP],
        ],
        axis=1,
    )
    return P, Z - pred


def fit_models(
    data: StrideData,
    train: Sequence[int] | None = None,
    *,
    order: int = 20,
    torque_order: int = 20,
    grams: tuple[list[Gram], list[Gram]] | None = None,
    sensor_variance: Array = SENSOR_VARIANCE,
) -> TrainedModel:
    """Fit gait model, noise model and torque profile on the subjects ``train`` (default: all).

    ``Sigma_xsub`` comes from each training subject's residuals against the model fitted on the other
    training subjects (seed 000 II-C4), so at least two training subjects are needed.
    """
    train = list(range(len(data.subjects))) if train is None else list(train)
    if len(train) < 2:
        raise ValueError("at least two subjects are needed (the noise model is cross-validated)")
    g_gait, g_torque = grams or subject_grams(data, order, torque_order)
    coef = fit_outputs(_sum(g_gait, train), order)
    phases, res = [], []
    for s in train:
        inner = fit_outputs(_sum(g_gait, [o for o in train if o != s]), order)
        ph, e = residuals(data, s, inner)
        phases.append(ph)
        res.append(e)
    # LocoHub's 150 samples per stride sit at phases i / 149, so i = 149 is the next heel strike and
    # there are 149 distinct phases per cycle: one residual bin each (seed 000 speaks of 150 bins).
    cov = residual_covariance(np.concatenate(phases), np.concatenate(res), n_bins=SAMPLES_PER_STRIDE - 1)
    noise = NoiseModel(cov, np.asarray(sensor_variance))
    torque = TorqueProfile(fit_torque(_sum(g_torque, train), torque_order))
    return TrainedModel(
        coef=coef, noise=noise, torque=torque, outputs=data.outputs, fingerprints=fingerprint_map(data, train)
    )


def fingerprint_map(data: StrideData, train: Sequence[int] | None = None) -> FingerprintMap | None:
    """Seed 004's personalization map from the subjects ``train`` (default all): their level strides
    (all strides when none is level), thigh angle against phase and stride length in metres. None when
    the table has no thigh angle or the subjects' data do not determine it."""
    if data.thigh is None:
        return None
    train = list(range(len(data.subjects))) if train is None else list(train)
    level = np.abs(data.r) < 1e-9
    walks = []
    for s in train:
        m = (data.subject == s) & (level if level.any() else True)
        n = int(m.sum())
        p = np.broadcast_to(data.p, (n, SAMPLES_PER_STRIDE)).reshape(-1)
        length = np.repeat(data.l[m] * data.leg_length[m], SAMPLES_PER_STRIDE)
        walks.append((p, length, data.thigh[m].reshape(-1)))
    try:
        return fit_map(walks)
    except ValueError:
        return None


def _sum(grams: Sequence[Gram], idx: Sequence[int]) -> Gram:
    total = grams[idx[0]]
    for i in idx[1:]:
        total = total + grams[i]
    return total
