"""Fitted-model files: save, load, and the model that ships with gaitscope.

A model file is a NumPy ``.npz`` archive (no pickles) holding the arrays of a
:class:`~gaitscope.estimators.pipeline.TrainedModel` and a JSON :class:`~gaitscope.sessions.schema.ModelProvenance` that
records what it was trained on. Loading checks the format version and every array's shape, so a
truncated or foreign file is refused with a message naming it. Writes are atomic.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import zipfile
from importlib import metadata, resources
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

from gaitscope.estimators.fingerprint import FingerprintMap
from gaitscope.estimators.gait_model import N_CHANNELS, N_OUTPUTS, NoiseModel
from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.estimators.torque import TorqueProfile
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.files import atomic_output
from gaitscope.sessions.schema import ModelProvenance

DEFAULT_MODEL_NAME = "default_model.npz"


def default_model_path() -> Path:
    """The model that ships with gaitscope, trained on the default cohort."""
    return Path(str(resources.files("gaitscope.sessions") / "data" / DEFAULT_MODEL_NAME))


def gaitscope_version() -> str:
    try:
        return metadata.version("gaitscope")
    except metadata.PackageNotFoundError:
        return "0+unknown"


def provenance(source: str, source_hash: str, **fields: object) -> ModelProvenance:
    """A provenance record stamped with the current version and UTC time."""
    return ModelProvenance(
        gaitscope_version=gaitscope_version(),
        created_utc=dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        source=source,
        source_sha256=source_hash,
        **fields,  # type: ignore[arg-type]
    )


def hash_arrays(*arrays: np.ndarray) -> str:
    """sha256 over the bytes of arrays (the training data's fingerprint)."""
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def save_model(path: str | Path, model: TrainedModel, prov: ModelProvenance) -> None:
    """Write ``model`` and its provenance to ``path`` atomically."""
    arrays: dict[str, Any] = {
        "coef": model.coef,
        "residual_cov": model.noise.residual_cov,
        "sensor_var": model.noise.sensor_var,
        "torque_coef": model.torque.coef,
        "torque_scale": np.float64(model.torque.scale),
        "torque_cutoff": np.float64(model.torque.cutoff_phase),
        "outputs": np.array(model.outputs, dtype=bool),
        "provenance": np.array(prov.model_dump_json()),
        **_fingerprint_arrays(model.fingerprints),
    }
    with atomic_output(Path(path)) as tmp, tmp.open("wb") as f:
        np.savez(f, **arrays)


#: The arrays of a fingerprint map in a model file (``fp_`` + FingerprintMap field).
_FP_FIELDS = ("xi_avg", "p_map", "explained", "fit_rmse_deg", "gram", "training_g")


def _fingerprint_arrays(fmap: FingerprintMap | None) -> dict[str, np.ndarray]:
    if fmap is None:
        return {}
    out = {f"fp_{k}": np.asarray(getattr(fmap, k), dtype=np.float64) for k in _FP_FIELDS}
    out["fp_order"] = np.array(fmap.order, dtype=np.int64)
    return out


def _fingerprints(arrays: dict[str, np.ndarray], name: str) -> FingerprintMap | None:
    """The file's fingerprint map; None in files written before maps existed (or trained without thigh)."""
    if "fp_xi_avg" not in arrays:
        return None
    missing = [f"fp_{k}" for k in (*_FP_FIELDS, "order") if f"fp_{k}" not in arrays]
    if missing:
        raise DataFormatError(f"model file lacks {', '.join(missing)}", file=name)
    order = int(arrays["fp_order"])
    c = 2 * (2 * order - 1)
    xi, pm, ex, rm, g, tg = (arrays[f"fp_{k}"] for k in _FP_FIELDS)
    checks = [
        ("fp_training_g", tg.ndim == 2 and tg.shape[1] == pm.shape[0]),
        ("fp_xi_avg", xi.shape == (c,)),
        ("fp_p_map", pm.ndim == 2 and pm.shape[1] == c and pm.shape[0] >= 1),
        ("fp_explained", ex.ndim == 1),
        ("fp_fit_rmse_deg", rm.ndim == 1 and rm.size >= 1),
        ("fp_gram", g.shape == (c, c)),
    ]
    for key, ok in checks:
        if not ok:
            raise DataFormatError(f"array {key!r} has the wrong shape {arrays[key].shape}", file=name)
        if not np.all(np.isfinite(arrays[key])):
            raise DataFormatError(f"array {key!r} holds NaN or inf", file=name)
    return FingerprintMap(
        xi_avg=xi.astype(np.float64),
        p_map=pm.astype(np.float64),
        explained=ex.astype(np.float64),
        fit_rmse_deg=rm.astype(np.float64),
        gram=g.astype(np.float64),
        order=order,
        training_g=tg.astype(np.float64),
    )


def load_model(path: str | Path) -> tuple[TrainedModel, ModelProvenance]:
    """Read a model file; :class:`DataFormatError` if it is not a valid gaitscope model."""
    name = str(path)
    try:
        with np.load(path, allow_pickle=False) as f:
            arrays = {k: f[k] for k in f.files}
    except FileNotFoundError:
        raise DataFormatError("no such model file", file=name) from None
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as e:
        raise DataFormatError(f"not a gaitscope model file ({e})", file=name) from None
    need = (
        "coef",
        "residual_cov",
        "sensor_var",
        "torque_coef",
        "torque_scale",
        "torque_cutoff",
        "provenance",
    )
    missing = [k for k in need if k not in arrays]
    if missing:
        raise DataFormatError(f"model file lacks {', '.join(missing)}", file=name)
    try:
        prov = ModelProvenance.model_validate(json.loads(str(arrays["provenance"])))
    except (ValidationError, json.JSONDecodeError) as e:
        raise DataFormatError(f"model provenance is invalid: {e}", file=name) from None
    coef, cov, var, tcoef = (arrays[k] for k in ("coef", "residual_cov", "sensor_var", "torque_coef"))
    K = 2 * prov.fourier_order + 1
    Kt = 2 * prov.torque_fourier_order + 1
    checks = [
        ("coef", coef.shape == (N_OUTPUTS, 2, 2, K)),
        ("residual_cov", cov.ndim == 3 and cov.shape[1:] == (N_CHANNELS, N_CHANNELS)),
        ("sensor_var", var.shape == (N_CHANNELS,)),
        ("torque_coef", tcoef.shape == (2, 2, Kt)),
    ]
    for key, ok in checks:
        if not ok:
            raise DataFormatError(f"array {key!r} has the wrong shape {arrays[key].shape}", file=name)
    for key in ("coef", "residual_cov", "sensor_var", "torque_coef"):
        if not np.all(np.isfinite(arrays[key])):
            raise DataFormatError(f"array {key!r} holds NaN or inf", file=name)
    model = TrainedModel(
        coef=coef.astype(np.float64),
        noise=NoiseModel(cov.astype(np.float64), var.astype(np.float64)),
        torque=TorqueProfile(tcoef.astype(np.float64), float(arrays["torque_scale"]), float(arrays["torque_cutoff"])),
        outputs=_outputs(arrays.get("outputs"), name),
        fingerprints=_fingerprints(arrays, name),
    )
    return model, prov


def _outputs(value: np.ndarray | None, name: str) -> tuple[bool, bool, bool, bool]:
    """The trained-outputs flags; files written before they existed trained all four."""
    if value is None:
        return (True, True, True, True)
    if value.shape != (4,):
        raise DataFormatError(f"array 'outputs' has the wrong shape {value.shape}", file=name)
    foot, shank, fwd, up = (bool(v) for v in value)
    return (foot, shank, fwd, up)
