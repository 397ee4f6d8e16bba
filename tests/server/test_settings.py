"""The one settings object: environment, defaults, and the refusal of unsafe ones."""

from __future__ import annotations

from pathlib import Path

import pytest
from pydantic import ValidationError

from server.settings import Settings


def test_defaults_are_local_and_embedded(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    s = Settings()
    assert s.host == "127.0.0.1" and s.is_loopback and s.port == 8000 and s.viser_port == 8081
    assert s.database_url == "sqlite:///gaitscope-data/gaitscope.db" and s.demo


def test_environment_overrides(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("GAITSCOPE_PORT", "9100")
    monkeypatch.setenv("GAITSCOPE_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("GAITSCOPE_DATABASE_URL", "sqlite:///elsewhere.db")
    monkeypatch.setenv("GAITSCOPE_DEMO", "false")
    s = Settings()
    assert (s.port, s.data_dir, s.database_url, s.demo) == (9100, tmp_path, "sqlite:///elsewhere.db", False)


def test_non_loopback_is_refused_in_production_and_flagged_in_development() -> None:
    with pytest.raises(ValidationError, match=r"refusing to listen on 0\.0\.0\.0 in production"):
        Settings(host="0.0.0.0", environment="production")
    assert not Settings(host="0.0.0.0").is_loopback  # allowed in development; `serve` prints a warning
    assert Settings(host="localhost").is_loopback and Settings(host="::1").is_loopback


def test_bad_values_are_refused() -> None:
    with pytest.raises(ValidationError, match="port"):
        Settings(port=70000)
    with pytest.raises(ValidationError, match="max_upload_mb"):
        Settings(max_upload_mb=0)


def test_disk_thresholds(monkeypatch: pytest.MonkeyPatch) -> None:
    s = Settings()
    assert (s.disk_warn_mb, s.disk_stop_mb) == (512, 128)
    monkeypatch.setenv("GAITSCOPE_DISK_WARN_MB", "2048")
    monkeypatch.setenv("GAITSCOPE_DISK_STOP_MB", "512")
    assert (Settings().disk_warn_mb, Settings().disk_stop_mb) == (2048, 512)
    with pytest.raises(ValidationError, match=r"disk_stop_mb \(600\) must not be above disk_warn_mb \(500\)"):
        Settings(disk_warn_mb=500, disk_stop_mb=600)
    with pytest.raises(ValidationError, match="disk_stop_mb"):
        Settings(disk_stop_mb=0)
