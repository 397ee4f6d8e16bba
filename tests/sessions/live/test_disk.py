"""The disk-space guard: free bytes as statvfs reports them, levels, hysteresis, errors and cost."""

from __future__ import annotations

import errno
import os
import time
from pathlib import Path

import pytest

from gaitscope.server.bench.disk_rate import CHANNEL_SETS, measure
from gaitscope.sessions.live.disk import MIB, DiskGuard, GrowthRate, estimated_bytes_per_s, free_bytes, minutes


class FakeDisk:
    """A ``free`` function whose answer the test sets (MiB), or an error to raise."""

    def __init__(self, free_mb: float):
        self.free_mb = free_mb
        self.error: OSError | None = None
        self.paths: list[Path] = []

    def __call__(self, path: Path) -> int:
        self.paths.append(path)
        if self.error is not None:
            raise self.error
        return round(self.free_mb * MIB)


def test_free_bytes_is_what_statvfs_gives_an_unprivileged_user(tmp_path: Path) -> None:
    st = os.statvfs(tmp_path)
    assert abs(free_bytes(tmp_path) - st.f_bavail * st.f_frsize) < 64 * MIB  # other writers may run meanwhile
    assert free_bytes(tmp_path) < st.f_bfree * st.f_frsize + 64 * MIB  # root's reserve is not counted


def test_free_bytes_of_a_path_not_yet_created_is_measured_at_its_parent(tmp_path: Path) -> None:
    missing = tmp_path / "data" / "recordings" / "x.mcap"
    assert abs(free_bytes(missing) - free_bytes(tmp_path)) < 64 * MIB
    assert not (tmp_path / "data").exists()


def test_levels_fall_at_once_and_rise_past_a_margin(tmp_path: Path) -> None:
    disk = FakeDisk(free_mb=2000)
    guard = DiskGuard(tmp_path, warn_mb=1024, stop_mb=256, hysteresis_mb=16, free=disk)
    assert guard.level == "ok" and guard.free is None
    steps = [
        (2000, "ok"),
        (1024, "ok"),  # at the threshold: not below it
        (1023.9, "low"),
        (1030, "low"),  # back above 1024 but within the 16 MiB margin
        (1040, "ok"),
        (1000, "low"),
        (255, "critical"),
        (260, "critical"),  # within the margin above 256
        (300, "low"),
        (100, "critical"),
        (1035, "low"),  # from critical straight past the warning threshold: still the margin
        (5000, "ok"),
    ]
    for free_mb, level in steps:
        disk.free_mb = free_mb
        assert guard.check() == level == guard.level, free_mb
        assert guard.free == round(free_mb * MIB) and guard.free_mb == pytest.approx(free_mb, abs=1e-6)
    assert disk.paths == [tmp_path] * len(steps)


def test_without_hysteresis_the_level_follows_the_thresholds(tmp_path: Path) -> None:
    disk = FakeDisk(free_mb=100)
    guard = DiskGuard(tmp_path, warn_mb=100, stop_mb=10, hysteresis_mb=0, free=disk)
    levels = []
    for free_mb in (100, 99, 100, 9, 10):
        disk.free_mb = free_mb
        levels.append(guard.check())
    assert levels == ["ok", "low", "ok", "critical", "low"]


def test_a_failed_measurement_is_critical_until_one_works(tmp_path: Path) -> None:
    disk = FakeDisk(free_mb=5000)
    guard = DiskGuard(tmp_path, warn_mb=1024, stop_mb=256, free=disk)
    assert guard.check() == "ok"
    disk.error = OSError(errno.EIO, "Input/output error")
    assert guard.check() == "critical"
    assert guard.free is None and guard.free_mb is None and guard.error is disk.error
    disk.error = None
    assert guard.check() == "ok" and guard.error is None  # 5000 MiB is far past the margin


def test_a_vanished_folder_is_measured_at_its_parent(tmp_path: Path) -> None:
    data = tmp_path / "data"
    data.mkdir()
    guard = DiskGuard(data, warn_mb=0, stop_mb=0)
    assert guard.check() == "ok"
    data.rmdir()
    assert guard.check() == "ok" and guard.error is None


def test_thresholds_are_checked(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"the stop threshold \(300 MiB\) must not be above the warning one"):
        DiskGuard(tmp_path, warn_mb=200, stop_mb=300)
    with pytest.raises(ValueError, match="at least 0 MiB"):
        DiskGuard(tmp_path, warn_mb=200, stop_mb=-1)
    assert DiskGuard(tmp_path, warn_mb=200, stop_mb=200).check() in ("ok", "critical")  # warning disabled


def test_real_thresholds_against_the_real_disk(tmp_path: Path) -> None:
    free_mb = free_bytes(tmp_path) / MIB
    assert DiskGuard(tmp_path, warn_mb=free_mb / 4, stop_mb=free_mb / 8).check() == "ok"
    assert DiskGuard(tmp_path, warn_mb=free_mb * 4, stop_mb=free_mb / 8).check() == "low"
    assert DiskGuard(tmp_path, warn_mb=free_mb * 8, stop_mb=free_mb * 4).check() == "critical"


def test_a_check_is_cheap_enough_for_once_a_second(tmp_path: Path) -> None:
    guard = DiskGuard(tmp_path / "data" / "recordings", warn_mb=1024, stop_mb=256)
    n = 1000
    start = time.perf_counter()
    for _ in range(n):
        guard.check()
    per_check = (time.perf_counter() - start) / n
    assert per_check < 1e-3  # a few microseconds in practice: a statvfs and two stats


# --- what a recording takes, in minutes --------------------------------------------------------------


@pytest.mark.parametrize("name", list(CHANNEL_SETS))
def test_the_estimate_is_what_the_recorder_writes(name: str) -> None:
    """The constants of sessions.live.disk against the real pipeline and recorder (server/bench/disk_rate.py)."""
    measured = measure(CHANNEL_SETS[name], 200.0, 15.0)
    estimate = estimated_bytes_per_s(200.0, measured.channels, len(measured.estimators))
    assert estimate == pytest.approx(measured.bytes_per_s, rel=0.15), (name, measured.bytes_per_s)
    assert measured.bytes_per_s > 60_000  # twice the 29 KiB/s once assumed, at the least


def test_an_undeclared_device_is_estimated_as_the_walking_set() -> None:
    assert estimated_bytes_per_s(200.0, None, 13) == estimated_bytes_per_s(200.0, 7, 13)
    assert estimated_bytes_per_s(100.0, 7, 3) == pytest.approx(estimated_bytes_per_s(200.0, 7, 3) / 2)


def test_growth_is_the_estimate_until_measured_over_its_window() -> None:
    rate = GrowthRate(estimate=100_000.0, window_s=10.0)
    assert rate.bytes_per_s == 100_000.0
    for s in range(10):  # 300 kB/s for 9 s: not yet a window
        rate.update(300_000 * s, float(s))
    assert rate.bytes_per_s == 100_000.0
    assert rate.update(300_000 * 10, 10.0) == pytest.approx(300_000.0)
    for s in range(11, 40):  # it slows to 50 kB/s: followed within a window
        rate.update(3_000_000 + 50_000 * (s - 10), float(s))
    assert rate.bytes_per_s == pytest.approx(50_000.0)
    rate.update(1000, 40.0)  # a new trial's file: measured again from there
    assert rate.bytes_per_s == 100_000.0


def test_minutes_of_recording() -> None:
    assert minutes(60 * 300_000, 300_000.0) == pytest.approx(1.0)
    assert minutes(0, 300_000.0) == minutes(-5, 1.0) == 0.0
    assert minutes(1, 0.0) == float("inf")
    guard = DiskGuard(".", warn_mb=512, stop_mb=128, free=FakeDisk(free_mb=640))
    assert guard.room() is None
    guard.check()
    assert guard.room() == 512 * MIB
