"""A subject's speed-change intent model (seed 001): the variant and the step-length model their filter runs.

Seed 001 fits eq. 1's kappa for each user from their own walks (and, for a user with an incomplete spinal
cord injury, eq. 14's hip-current model alpha). gaitscope's default for a new walker is the cohort's kappa
(:data:`gaitscope.estimators.intent.COHORT`; on the cohort a subject's own kappa did no better,
``docs/results.md``). A clinic that wants the paper's per-user model, or the iSCI variant, sets it here:

- **from a trial** of the subject's (a calibration walk with speed changes serves best; the fingerprint
  walk can be the same trial): the live estimator runs over the trial's frames as a session runs it, and
  kappa (and, for ``isci``, alpha) is fitted by least squares with seed 001's labels over its steps
  (:func:`gaitscope.estimators.intent.fit_kappa`). A trial without the channels, or with fewer than
  :data:`MIN_STEPS` usable steps, or with a fit outside :data:`KAPPA_RANGE`, is refused with the reason;
- **without a trial**: the variant's default (the cohort's kappa; seed 001's iSCI tuning).

The model is stored per subject (table ``intent_models``, migration ``0008_intent_models``), runs from the
subject's next session on, and is written into every recording's metadata (:data:`INTENT_MODEL_KEY`), so a
re-run of the recording runs what ran.
"""

from __future__ import annotations

import datetime as dt
import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Final

import numpy as np

from gaitscope.estimators.intent import COHORT, ISCI, BKFConfig, fit_alpha, fit_kappa
from gaitscope.estimators.intent_estimator import IntentEstimator
from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.formats.mcap_io import iter_sensor_frames
from gaitscope.sessions.personalization.tables import IntentModelRow
from gaitscope.sessions.store import NotFound, Store

__all__ = [
    "INTENT_MODEL_KEY",
    "KAPPA_RANGE",
    "MIN_STEPS",
    "IntentFitRefused",
    "IntentModels",
    "config_of",
    "default_model",
    "fit_from_trial",
    "from_metadata",
    "to_metadata",
]

#: Fewest usable steps a fit takes (seed 001 fitted on a few walks of 20-30 steps).
MIN_STEPS: Final = 20
#: Each kappa component a fit may give (seed 001's uninjured [0.33, 0.26, 0.38], iSCI [0.08, 0.06, 0.40], the
#: cohort's [0.24, 0.36, 0.42]); beyond it the walk did not determine the model (no speed change, say).
KAPPA_RANGE: Final = (-0.5, 1.5)
#: The recording metadata key of the intent model the session ran (JSON of kappa, alpha, variant).
INTENT_MODEL_KEY: Final = "intent_model"


class IntentFitRefused(ValueError):
    """A trial that cannot fit an intent model; the message says why and what would do."""


def _model(r: IntentModelRow) -> schema.IntentModel:
    return schema.IntentModel(
        subject_id=r.subject_id,
        variant=r.variant,  # type: ignore[arg-type]
        kappa=tuple(json.loads(r.kappa)),
        alpha=None if r.alpha is None else tuple(json.loads(r.alpha)),
        source=r.source,
        source_trial_id=r.source_trial_id,
        steps=r.steps,
        step_rmse_m=r.step_rmse_m,
        actor=r.actor,
        updated_utc=r.updated_utc,
        note=r.note,
    )


class IntentModels:
    """The ``intent_models`` table of ``store``."""

    def __init__(self, store: Store):
        self.store = store

    def get(self, subject_id: int) -> schema.IntentModel | None:
        """The subject's model (None: the default, the cohort's kappa)."""
        with self.store.reading() as session:
            row = session.get(IntentModelRow, subject_id)
            return None if row is None else _model(row)

    def save(self, model: schema.IntentModel) -> schema.IntentModel:
        """Keep ``model`` for its subject, replacing the one before (stamped now)."""
        now = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
        values = {
            "variant": model.variant,
            "kappa": json.dumps(list(model.kappa)),
            "alpha": None if model.alpha is None else json.dumps(list(model.alpha)),
            "source": model.source[:200],
            "source_trial_id": model.source_trial_id,
            "steps": model.steps,
            "step_rmse_m": model.step_rmse_m,
            "actor": model.actor,
            "updated_utc": now,
            "note": model.note,
        }
        with self.store.writing() as session:
            row = session.get(IntentModelRow, model.subject_id, with_for_update=True)
            if row is None:
                row = IntentModelRow(subject_id=model.subject_id, **values)
                session.add(row)
            else:
                for k, v in values.items():
                    setattr(row, k, v)
            session.flush()
            return _model(row)

    def delete(self, subject_id: int) -> None:
        """Back to the default.

        Raises:
            NotFound: the subject has no model of their own.
        """
        with self.store.writing() as session:
            row = session.get(IntentModelRow, subject_id, with_for_update=True)
            if row is None:
                raise NotFound(f"subject {subject_id} runs the default intent model already")
            session.delete(row)


def config_of(model: schema.IntentModel | None) -> BKFConfig:
    """The filter's tuning for a subject's model (None: :data:`COHORT`): the variant's noise (seed 001's
    uninjured or iSCI) with the model's kappa and alpha."""
    if model is None:
        return COHORT
    base = ISCI if model.variant == "isci" else COHORT
    return replace(base, kappa=model.kappa, alpha=model.alpha)


def default_model(subject_id: int, variant: schema.IntentVariant, actor: str, note: str = "") -> schema.IntentModel:
    """The variant's default: the cohort's kappa (``uninjured``), seed 001's iSCI tuning (``isci``)."""
    base = ISCI if variant == "isci" else COHORT
    source = "seed 001's iSCI tuning" if variant == "isci" else "the cohort's kappa (the default)"
    return schema.IntentModel(
        subject_id=subject_id, variant=variant, kappa=base.kappa, alpha=base.alpha, source=source, steps=0,
        step_rmse_m=None, actor=actor, updated_utc="", note=note,
    )  # fmt: skip


def _samples(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Times and the intent estimator's input matrix (its ``inputs`` then ``optional_inputs``) of a trial."""
    names = [*IntentEstimator.inputs, *IntentEstimator.optional_inputs]
    t: list[float] = []
    rows: list[list[float]] = []
    for _, raw in iter_sensor_frames(path):
        frame, _ = raw.plausible()
        t.append(frame.t)
        rows.append([math.nan if (v := getattr(frame, n, None)) is None else float(v) for n in names])
    return np.array(t, dtype=np.float64), np.array(rows, dtype=np.float64).reshape(-1, len(names))


def fit_from_trial(
    path: Path, leg_length_m: float, variant: schema.IntentVariant
) -> tuple[tuple[float, float, float], tuple[float, float] | None, int, float]:
    """``(kappa, alpha, steps, step RMSE)`` fitted on a recorded trial (see the module docstring).

    Raises:
        IntentFitRefused: the trial lacks the channels or the steps, or the fit makes no sense.
        DataFormatError: the file cannot be read.
    """
    from gaitscope.sessions.offline.intent_study import log_steps, step_data

    t, z = _samples(path)
    names = [*IntentEstimator.inputs, *IntentEstimator.optional_inputs]
    absent = [n for i, n in enumerate(names[: len(IntentEstimator.inputs)]) if not np.isfinite(z[:, i]).any()]
    absent = [n for n in absent if not n.startswith("com_")] + ([] if _has_com(z, names) else ["com_forward_*"])
    if absent or len(t) < 2:
        raise IntentFitRefused(f"the trial does not record {', '.join(absent) or 'any frame'}")
    if variant == "isci" and not np.isfinite(z[:, names.index("motor_current_A")]).any():
        raise IntentFitRefused(
            "the iSCI variant's current model needs motor_current_A, which the trial does not record"
        )
    base = ISCI if variant == "isci" else COHORT
    try:
        log = log_steps(leg_length_m, base, t, z, episodes=None)
    except ValueError as exc:  # time not increasing
        raise DataFormatError(f"the trial's frames cannot run the intent filter: {exc}", file=str(path)) from exc
    steps = step_data(log)
    ok = np.isfinite(np.column_stack(steps)).all(axis=1)
    n = int(ok.sum())
    if n < MIN_STEPS:
        raise IntentFitRefused(
            f"{n} usable steps (touchdown and mid-stance, walking forwards); at least {MIN_STEPS} needed"
        )
    try:
        kappa = fit_kappa([steps], [leg_length_m])
    except ValueError as exc:
        raise IntentFitRefused(str(exc)) from None
    lo, hi = KAPPA_RANGE
    if not (np.isfinite(kappa).all() and ((kappa > lo) & (kappa < hi)).all()):
        raise IntentFitRefused(
            f"the fit gave kappa {np.round(kappa, 3).tolist()}, outside {lo}..{hi}: the walk does not determine the "
            "step-length model (walk at two or more speeds, with changes)"
        )
    v0, v1, length = steps
    rmse = float(np.sqrt(np.mean((length - (kappa[0] * v0 + kappa[1] * (v1 - v0) + kappa[2] * leg_length_m))[ok] ** 2)))
    alpha = None
    if variant == "isci":
        try:
            a = fit_alpha([step_data(log, current=True)])
        except ValueError as exc:
            raise IntentFitRefused(f"the current model: {exc}") from None
        if not np.isfinite(a).all():
            raise IntentFitRefused("the current model's fit is not finite")
        alpha = (float(a[0]), float(a[1]))
    return (float(kappa[0]), float(kappa[1]), float(kappa[2])), alpha, n, rmse


def _has_com(z: np.ndarray, names: list[str]) -> bool:
    return all(np.isfinite(z[:, names.index(n)]).any() for n in ("com_forward_m", "com_forward_vel_m_s"))


def to_metadata(config: BKFConfig, variant: str) -> str:
    """The recording metadata value for the model a session runs."""
    return json.dumps({"variant": variant, "kappa": list(config.kappa), "alpha": config.alpha})


def from_metadata(text: str | None, file: str = "") -> BKFConfig | None:
    """The recorded model's tuning (None: the recording has none: it ran :data:`COHORT`)."""
    if not text:
        return None
    try:
        d = json.loads(text)
        kappa = tuple(float(x) for x in d["kappa"])
        alpha = None if d.get("alpha") is None else tuple(float(x) for x in d["alpha"])
        variant = d["variant"]
    except (ValueError, KeyError, TypeError):
        raise DataFormatError(f"bad recorded intent model {text[:80]!r}", file=file) from None
    if len(kappa) != 3 or (alpha is not None and len(alpha) != 2) or variant not in ("uninjured", "isci"):
        raise DataFormatError(f"bad recorded intent model {text[:80]!r}", file=file)
    if not all(math.isfinite(x) for x in (*kappa, *(alpha or ()))):
        raise DataFormatError("the recorded intent model is not finite", file=file)
    base = ISCI if variant == "isci" else COHORT
    return replace(base, kappa=(kappa[0], kappa[1], kappa[2]), alpha=None if alpha is None else (alpha[0], alpha[1]))
