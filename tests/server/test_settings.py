"""The one settings object: environment, defaults, and the refusal of unsafe ones."""

from __future__ import annotations

from pathlib import Path

import pytest
from pydantic import ValidationError

from gaitscope.server.settings import Settings


def test_defaults_are_local_and_embedded(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("GAITSCOPE_DATABASE_URL", raising=False)  # set in the PostgreSQL run (tests/conftest.py)
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


def test_non_loopback_needs_accounts_and_tls() -> None:
    for env in ("development", "production"):
        with pytest.raises(ValidationError, match=r"refusing to listen on 0\.0\.0\.0 without accounts .* and TLS"):
            Settings(host="0.0.0.0", environment=env)
    with pytest.raises(ValidationError, match=r"without accounts \(GAITSCOPE_AUTH=true\): bind"):
        Settings(host="0.0.0.0", behind_tls_proxy=True)
    with pytest.raises(ValidationError, match=r"without TLS"):
        Settings(host="10.0.0.5", auth=True)
    with pytest.raises(ValidationError, match=r"tls_cert and tls_key go together"):
        Settings(auth=True, tls_cert="cert.pem")
    behind_proxy = Settings(host="0.0.0.0", auth=True, behind_tls_proxy=True)
    assert not behind_proxy.is_loopback and behind_proxy.tls
    own_tls = Settings(host="10.0.0.5", auth=True, tls_cert="c.pem", tls_key="k.pem")
    assert own_tls.tls and not Settings().tls
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


def test_the_websocket_message_limit_holds_a_device_frame(monkeypatch: pytest.MonkeyPatch) -> None:
    assert Settings().ws_max_kb == 64
    monkeypatch.setenv("GAITSCOPE_WS_MAX_KB", "16")
    assert Settings().ws_max_kb == 16  # MAX_FRAME_BYTES, 16 KiB: a frame of every channel four times over
    with pytest.raises(ValidationError, match="ws_max_kb"):
        Settings(ws_max_kb=15)
