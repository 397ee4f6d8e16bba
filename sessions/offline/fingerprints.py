"""Seed 004's leave-one-subject-out study of gait fingerprints, on the virtual cohort.

``gaitscope crossval --study fingerprints``. Protocol (seed 004 Sec. IV, ``shared/reference/estimators.md``
section 2), with the cohort standing in for the Embry data set:

- training data: each subject's level walking at 0.8, 1.0 and 1.2 m/s (20 strides each, the cohort's
  reported thigh angle, which carries the subject's sensor offset); for each held-out subject the map
  (:func:`gaitscope.estimators.fingerprint.fit_map`) is learnt from the other nine;
- test walk: the held-out subject at ``SCHEDULE`` (26 strides per block), ``dt = 1 / (150 pdot_true)``
  (150 samples per stride), thigh velocity by numerical differentiation of the angle (``numpy.gradient``
  over time, as the paper differentiated its motion-capture angles; a choice of scheme);
- three filters: AVG (the average model), LS-GF (the least-squares fingerprint of the held-out subject's
  own training-format data, the ground truth, as the paper "fed in the ground truth"), GF (fingerprint
  states estimated online);
- RMSE of phase (wrapped), phase rate and stride length over the samples after the first 20 strides;
  a subject on whom any filter does not converge (phase RMSE above ``CONVERGED_PHASE_RMSE``) is left
  out of the means, as the paper left out AB10; one-sided paired t-tests over subjects.

The cohort's blocks morph into each other over one stride, whereas the paper's data jumped between
speeds; the cohort is smoother there (easier).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Final

import numpy as np
import pandas as pd
from scipy import stats

from gaitscope.estimators.fingerprint import FingerprintConfig, FingerprintEKF, FingerprintMap, Mode, basis, fit_map
from gaitscope.sessions import schema
from gaitscope.sessions.offline.crossval import wrapped
from gaitscope.sessions.synth.cohort import CohortSpec, SubjectParams, generate_cohort, generate_walk, make_subjects

__all__ = [
    "CONVERGED_PHASE_RMSE",
    "PAPER_TABLE2",
    "PAPER_TABLE3",
    "SCHEDULE",
    "FingerprintStudy",
    "SubjectResult",
    "run_study",
    "to_markdown",
    "training_walks",
]

#: Seed 004's test schedule: speeds (m/s) of consecutive blocks of ``STRIDES_PER_BLOCK`` strides.
SCHEDULE: Final = (0.8, 1.0, 1.2, 1.0, 0.8, 1.0, 0.8, 1.0, 1.2)
STRIDES_PER_BLOCK: Final = 26
#: Errors are counted after this many strides (seed 004: "after the first 20 strides").
SKIP_STRIDES: Final = 20
SAMPLES_PER_STRIDE: Final = 150
TRAIN_SPEEDS: Final = (0.8, 1.0, 1.2)
#: A filter whose phase RMSE is above this did not converge (the paper's AB10 criterion is qualitative).
CONVERGED_PHASE_RMSE: Final = 0.1
MODES: Final[tuple[Mode, ...]] = ("gf", "avg", "ls")
LABELS: Final = {"gf": "GF", "avg": "AVG", "ls": "LS-GF"}
#: Seed 004 Table III means: phase, phase rate (1/s), stride length (m).
PAPER_TABLE3: Final = {
    "gf": (0.0259, 0.0431, 0.1043),
    "avg": (0.0189, 0.0232, 0.1122),
    "ls": (0.0170, 0.0227, 0.0780),
}
#: Seed 004 Table II: average-model and LS-GF fit RMSE (deg) of AB01..AB10.
PAPER_TABLE2: Final = (
    (20.4, 4.22), (8.23, 2.83), (3.52, 3.15), (25.1, 3.51), (8.64, 4.06),
    (10.1, 3.34), (8.39, 4.47), (16.2, 4.5), (6.6, 2.88), (4.17, 3.17),
)  # fmt: skip
#: Seed 004 Table I: cumulative variance of g1..g3, range over the ten folds.
PAPER_TABLE1: Final = ((0.95, 0.98), (0.98, 0.99), (0.99, 1.0))


def training_walks(spec: CohortSpec) -> tuple[list[str], list[tuple[np.ndarray, np.ndarray, np.ndarray]]]:
    """Each subject's level walking at :data:`TRAIN_SPEEDS`: codes and ``(phase, stride length m, thigh deg)``."""
    frame = generate_cohort(
        CohortSpec(
            n_subjects=spec.n_subjects,
            speeds_m_s=TRAIN_SPEEDS,
            inclines_deg=(0.0,),
            strides_per_condition=spec.strides_per_condition,
            samples_per_stride=SAMPLES_PER_STRIDE,
            seed=spec.seed,
        )
    )
    codes, walks = [], []
    for code, rows in frame.groupby(schema.SUBJECT, sort=True):
        codes.append(str(code))
        walks.append(_walk_arrays(rows))
    return codes, walks


def _walk_arrays(rows: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    p = rows[schema.PHASE_IPSI].to_numpy(np.float64) / 100.0 % 1.0
    return p, rows["stride_length_m"].to_numpy(np.float64), np.degrees(rows[schema.THIGH_ANGLE].to_numpy(np.float64))


@dataclass(frozen=True)
class HeldOutWalk:
    """A held-out subject's walk at :data:`SCHEDULE`, one sample per row (no repeated stride boundaries)."""

    t: np.ndarray
    phase: np.ndarray
    phase_rate: np.ndarray
    stride_length_m: np.ndarray
    thigh_deg: np.ndarray
    thigh_vel_dps: np.ndarray
    stride: np.ndarray


def held_out_walk(subject: SubjectParams, seed: int) -> HeldOutWalk:
    """The walk of the study for ``subject`` (its own random stream from ``seed``)."""
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(4, int(subject.code[2:]))))
    w = generate_walk(subject, [(v, 0.0, STRIDES_PER_BLOCK) for v in SCHEDULE], rng, SAMPLES_PER_STRIDE + 1)
    keep = w[schema.PHASE_IPSI].to_numpy() < 100.0  # each stride's last sample is the next one's first
    w = w[keep]
    t = w[schema.TIME_S].to_numpy(np.float64)
    thigh = np.degrees(w[schema.THIGH_ANGLE].to_numpy(np.float64))
    return HeldOutWalk(
        t=t,
        phase=w[schema.PHASE_IPSI].to_numpy(np.float64) / 100.0,
        phase_rate=w["phase_rate_ipsi_1_s"].to_numpy(np.float64),
        stride_length_m=w["stride_length_m"].to_numpy(np.float64),
        thigh_deg=thigh,
        thigh_vel_dps=np.gradient(thigh, t),
        stride=w[schema.STEP].to_numpy(),
    )


@dataclass(frozen=True)
class SubjectResult:
    """One fold: the held-out subject's errors per filter, fits, and the fold's map."""

    code: str
    rmse: dict[str, tuple[float, float, float]]  # mode -> (phase, phase rate, stride length)
    avg_fit_rmse_deg: float
    ls_fit_rmse_deg: float
    g_ls: tuple[float, ...]
    explained: tuple[float, ...]
    n_components: int

    @property
    def converged(self) -> bool:
        return all(r[0] <= CONVERGED_PHASE_RMSE for r in self.rmse.values())


def run_filter(fmap: FingerprintMap, mode: Mode, walk: HeldOutWalk, g: np.ndarray | None = None) -> np.ndarray:
    """``(n, 3)`` phase, phase rate and stride length of one filter over ``walk``."""
    ekf = FingerprintEKF(fmap, mode=mode, g=g, config=FingerprintConfig())
    out = np.empty((walk.t.size, 3))
    z = np.empty(2)
    for i in range(walk.t.size):
        z[0], z[1] = walk.thigh_deg[i], walk.thigh_vel_dps[i]
        y = ekf.step(float(walk.t[i]), z)
        out[i] = y[:3]
    return out


def _fold(
    k: int, codes: Sequence[str], walks: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]], subject: SubjectParams,
    seed: int, n_components: int | None,
) -> SubjectResult:  # fmt: skip
    fmap = fit_map([w for i, w in enumerate(walks) if i != k], n_components=n_components)
    p, l, theta = walks[k]
    g_ls = fmap.ls_fingerprint(p, l, theta)
    A = basis(p, l, fmap.order)
    avg_fit = float(np.sqrt(np.mean((A @ fmap.xi_avg - theta) ** 2)))
    ls_fit = float(np.sqrt(np.mean((A @ fmap.xi(g_ls) - theta) ** 2)))
    walk = held_out_walk(subject, seed)
    scored = walk.stride >= SKIP_STRIDES
    rmse = {}
    for mode in MODES:
        est = run_filter(fmap, mode, walk, g_ls if mode == "ls" else None)
        e_p = wrapped(est[scored, 0] - walk.phase[scored])
        e_r = est[scored, 1] - walk.phase_rate[scored]
        e_l = est[scored, 2] - walk.stride_length_m[scored]
        rmse[mode] = tuple(float(np.sqrt(np.mean(e**2))) for e in (e_p, e_r, e_l))
    return SubjectResult(
        code=codes[k],
        rmse=rmse,  # type: ignore[arg-type]
        avg_fit_rmse_deg=avg_fit,
        ls_fit_rmse_deg=ls_fit,
        g_ls=tuple(float(x) for x in g_ls),
        explained=tuple(float(x) for x in fmap.explained),
        n_components=fmap.n_components,
    )


@dataclass(frozen=True)
class FingerprintStudy:
    """The study's folds and the paired tests over the converged ones."""

    folds: list[SubjectResult]
    tests: dict[str, float] = field(default_factory=dict)  # name -> one-sided p

    @property
    def used(self) -> list[SubjectResult]:
        return [f for f in self.folds if f.converged]

    def mean(self, mode: str) -> tuple[float, float, float]:
        a = np.array([f.rmse[mode] for f in self.used])
        return (math.nan,) * 3 if a.size == 0 else tuple(float(x) for x in a.mean(axis=0))  # type: ignore[return-value]


def run_study(spec: CohortSpec | None = None, n_components: int | None = None) -> FingerprintStudy:
    """Every fold of the study on the cohort of ``spec`` (its subjects and seed; default the default cohort)."""
    spec = spec or CohortSpec()
    codes, walks = training_walks(spec)
    subjects = make_subjects(spec)
    folds = [_fold(k, codes, walks, subjects[k], spec.seed, n_components) for k in range(len(codes))]
    study = FingerprintStudy(folds)
    used = study.used
    if len(used) >= 2:
        col = {m: np.array([f.rmse[m] for f in used]) for m in MODES}

        def p(a: Mode, b: Mode, metric: int, alternative: str) -> float:
            return float(stats.ttest_rel(col[a][:, metric], col[b][:, metric], alternative=alternative).pvalue)

        study.tests.update(
            {
                "LS-GF < AVG, phase": p("ls", "avg", 0, "less"),
                "LS-GF < AVG, stride length": p("ls", "avg", 2, "less"),
                "GF > AVG, phase": p("gf", "avg", 0, "greater"),
                "GF < AVG, stride length": p("gf", "avg", 2, "less"),
            }
        )
    return study


def to_markdown(study: FingerprintStudy) -> str:
    """Tables III, II and I of seed 004 beside the cohort's, and the paired tests."""
    lines = [
        "Table III: RMSE, mean over converged held-out subjects "
        f"({len(study.used)} of {len(study.folds)}; cohort / paper)",
        "",
        "| filter | phase | phase rate (1/s) | stride length (m) |",
        "|---|---|---|---|",
    ]
    for m in MODES:
        ours, paper = study.mean(m), PAPER_TABLE3[m]
        cells = " | ".join(f"{o:.4f} / {q:.4f}" for o, q in zip(ours, paper, strict=True))
        lines.append(f"| {LABELS[m]} | {cells} |")
    lines += ["", "Paired one-sided t-tests over subjects (paper: LS-GF < AVG on phase and stride length, P < 0.05;"]
    lines += ["GF > AVG on phase, P < 0.001; GF vs AVG on stride length not significant, P = 0.774):", ""]
    lines += [f"- {name}: p = {p:.3g}" for name, p in study.tests.items()]
    lines += [
        "",
        "Table II: fit RMSE of the average model and of LS-GF on each held-out subject's level walking (deg),",
        "with its least-squares fingerprint; the paper's AB01..AB10 beside it",
        "",
        "| subject | AVG fit | LS-GF fit | g (LS) | paper AVG / LS-GF |",
        "|---|---|---|---|---|",
    ]
    for f, (pa, pl) in zip(study.folds, PAPER_TABLE2, strict=False):
        g = ", ".join(f"{x:.2f}" for x in f.g_ls)
        lines.append(f"| {f.code} | {f.avg_fit_rmse_deg:.2f} | {f.ls_fit_rmse_deg:.2f} | {g} | {pa} / {pl} |")
    lines += [
        "",
        "Table I: cumulative variance explained per component, per fold (paper: g1 0.95-0.98, g2 0.98-0.99, "
        "g3 0.99-1.0)",
        "",
        "| left out | g1 | g2 | g3 | g4 | kept |",
        "|---|---|---|---|---|---|",
    ]
    for f in study.folds:
        cells = " | ".join(f"{x:.3f}" for x in f.explained[:4])
        lines.append(f"| {f.code} | {cells} | {f.n_components} |")
    rows = []
    for f in study.folds:
        cells = " | ".join(" / ".join(f"{x:.4f}" for x in f.rmse[m]) for m in MODES)
        rows.append(f"| {f.code} | {cells} | {'yes' if f.converged else 'no'} |")
    per = "\n".join(rows)
    lines += [
        "",
        "Per subject: phase / phase rate / stride length RMSE",
        "",
        "| subject | GF | AVG | LS-GF | converged |",
        "|---|---|---|---|---|",
        per,
    ]
    return "\n".join(lines) + "\n"
