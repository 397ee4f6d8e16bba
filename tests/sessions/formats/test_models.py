"""Model files: round trip, provenance, and refusal of damaged files."""

from pathlib import Path

import numpy as np
import pytest

from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.formats.models import default_model_path, load_model, provenance, save_model


def _prov():
    return provenance(
        "default-cohort",
        "ab" * 32,
        subjects=("VC01", "VC02"),
        n_samples=300,
        n_strides=2,
        speeds_m_s=(1.0,),
        inclines_deg=(0.0,),
        fourier_order=20,
        torque_fourier_order=20,
    )


def test_round_trip(tmp_path: Path, small_model: TrainedModel) -> None:
    path = tmp_path / "m.npz"
    save_model(path, small_model, _prov())
    model, prov = load_model(path)
    np.testing.assert_array_equal(model.coef, small_model.coef)
    np.testing.assert_array_equal(model.noise.residual_cov, small_model.noise.residual_cov)
    np.testing.assert_array_equal(model.torque.coef, small_model.torque.coef)
    assert prov.subjects == ("VC01", "VC02") and prov.format_version == 1
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left


def test_missing_and_garbage_files_are_refused(tmp_path: Path) -> None:
    with pytest.raises(DataFormatError, match="no such model file"):
        load_model(tmp_path / "nope.npz")
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip at all")
    with pytest.raises(DataFormatError, match=r"file .*bad.npz: not a gaitscope model file"):
        load_model(bad)


def test_wrong_shapes_and_nan_are_refused(tmp_path: Path, small_model: TrainedModel) -> None:
    path = tmp_path / "m.npz"
    broken = TrainedModel(small_model.coef[:, :, :, :5], small_model.noise, small_model.torque)
    save_model(path, broken, _prov())
    with pytest.raises(DataFormatError, match="array 'coef' has the wrong shape"):
        load_model(path)
    coef = small_model.coef.copy()
    coef[0, 0, 0, 0] = np.nan
    save_model(path, TrainedModel(coef, small_model.noise, small_model.torque), _prov())
    with pytest.raises(DataFormatError, match="array 'coef' holds NaN or inf"):
        load_model(path)


def test_failed_save_keeps_the_old_file(tmp_path: Path, small_model: TrainedModel, monkeypatch) -> None:
    path = tmp_path / "m.npz"
    save_model(path, small_model, _prov())
    before = path.read_bytes()

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", boom)
    with pytest.raises(OSError, match="disk full"):
        save_model(path, small_model, _prov())
    assert path.read_bytes() == before
    assert list(tmp_path.iterdir()) == [path]


def test_the_shipped_model_loads_and_says_what_it_was_trained_on() -> None:
    model, prov = load_model(default_model_path())
    assert prov.source == "default-cohort" and len(prov.subjects) == 10
    assert prov.fourier_order == 20 and model.coef.shape == (4, 2, 2, 41)
    assert set(prov.speeds_m_s) == {0.8, 1.0, 1.2} and len(prov.inclines_deg) == 9


def test_trained_outputs_round_trip(tmp_path: Path, small_model: TrainedModel) -> None:
    from dataclasses import replace

    path = tmp_path / "m.npz"
    save_model(path, replace(small_model, outputs=(True, True, False, False)), _prov())
    model, _ = load_model(path)
    assert model.outputs == (True, True, False, False)
    assert model.channel_mask.tolist() == [True, True, True, True, False, False]
