"""Free space on the recordings' disk, checked against two thresholds: warn, then stop; and how many
minutes of recording that space is at a session's own rate.

What a recording takes depends on what the device sends and what the stack runs: each sample records
the sensor frame, every estimator's outputs, the gait state and the torque. Measured with
``python -m gaitscope.server.bench.disk_rate`` (cohort walking at 200 Hz, 60 s per row, index included)::

    channels                  estimators   kB/s   MiB/hour
    walking (7)                        3   76.6        263
    walking, not declared             13  130.5        448
    walking + 2 IMUs (19)              3  112.6        387
    all (74)                           6  317.5       1090

:func:`estimated_bytes_per_s` fits those rows (:data:`BYTES_PER_SAMPLE` and the two per-item figures) and is
a recording's rate until it has grown for a while; from then on :class:`GrowthRate` measures the file's own
growth. An hour's index adds ~1 MiB at :meth:`~gaitscope.sessions.formats.recording.Recorder.finish`, and crash
recovery writes a full copy of the file beside it before it replaces the original (on a full disk
:func:`~gaitscope.sessions.formats.mcap_io.recover_in_place` indexes it where it lies instead). The runtime calls
:meth:`DiskGuard.check` once a second: ``low`` warns the clinician, ``critical`` stops the recording cleanly
while there is still room to finish it, so a full disk (:class:`~gaitscope.sessions.formats.recording.RecordingError`)
stays the exception. The thresholds are MiB (the stop one is room to finish files, whatever the rate);
the events and data health state them as minutes of recording at the session's rate (:func:`minutes`).
"""

from __future__ import annotations

import shutil
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Final, Literal

__all__ = [
    "BYTES_PER_CHANNEL",
    "BYTES_PER_ESTIMATOR",
    "BYTES_PER_SAMPLE",
    "MIB",
    "DiskGuard",
    "DiskLevel",
    "GrowthRate",
    "estimated_bytes_per_s",
    "free_bytes",
    "minutes",
]

MIB: Final = 1024 * 1024
#: MCAP bytes per sample whatever is sent: gait state, torque command, chunk and index overhead (measured, above).
BYTES_PER_SAMPLE: Final = 187.0
#: More bytes per sample for each channel the device sends (a float in the sensor frame's JSON, compressed).
BYTES_PER_CHANNEL: Final = 16.5
#: More bytes per sample for each estimator of the session's stack (its outputs' JSON, compressed).
BYTES_PER_ESTIMATOR: Final = 27.0
#: Channels assumed for a device that does not declare them: the walking set.
UNDECLARED_CHANNELS: Final = 7


def estimated_bytes_per_s(rate_hz: float, channels: int | None, estimators: int) -> float:
    """What a recording of ``channels`` (None: not declared) and a stack of ``estimators`` at ``rate_hz`` takes
    (bytes/s), from the measurement in the module docstring (within 10 % of each of its rows)."""
    n = UNDECLARED_CHANNELS if channels is None else channels
    return rate_hz * (BYTES_PER_SAMPLE + BYTES_PER_CHANNEL * n + BYTES_PER_ESTIMATOR * estimators)


def minutes(room_bytes: float, bytes_per_s: float) -> float:
    """Minutes of recording ``room_bytes`` holds at ``bytes_per_s`` (0 for no room; inf for a rate of 0)."""
    if room_bytes <= 0:
        return 0.0
    return float("inf") if bytes_per_s <= 0 else room_bytes / bytes_per_s / 60.0


class GrowthRate:
    """A recording's bytes per second: the estimate until its file has grown for ``window_s``, then the growth
    measured over the last ``window_s`` (so a device that sends more or fewer channels than it declared, or a
    stack that changes, is followed).

    Args:
        estimate: the rate before there is a measurement (:func:`estimated_bytes_per_s`).
        window_s: how long a growth is measured over (s).
    """

    def __init__(self, estimate: float, window_s: float = 10.0):
        self.estimate = estimate
        self.window_s = window_s
        self._seen: deque[tuple[float, int]] = deque()

    def update(self, size: int, now: float) -> float:
        """Note the file's ``size`` (bytes) at ``now`` (s, monotonic) and return the rate. A smaller size than
        before (a new trial's file) starts the measurement again."""
        if self._seen and size < self._seen[-1][1]:
            self._seen.clear()
        self._seen.append((now, size))
        while len(self._seen) > 2 and now - self._seen[1][0] >= self.window_s:
            self._seen.popleft()
        return self.bytes_per_s

    @property
    def bytes_per_s(self) -> float:
        """The measured growth once it spans ``window_s``, else the estimate."""
        if len(self._seen) < 2:
            return self.estimate
        (t0, s0), (t1, s1) = self._seen[0], self._seen[-1]
        return self.estimate if t1 - t0 < self.window_s else (s1 - s0) / (t1 - t0)

#: ``ok``; ``low``: below the warning threshold; ``critical``: below the stop threshold, or unknown.
DiskLevel = Literal["ok", "low", "critical"]


def free_bytes(path: str | Path) -> int:
    """Bytes that gaitscope may still write on the file system holding ``path``.

    ``statvfs``'s ``f_bavail * f_frsize`` (via :func:`shutil.disk_usage`): the blocks reserved for
    root are not counted, so the figure holds whichever user the server runs as. A path that does
    not exist yet (the recordings folder before the first recording) is measured at its nearest
    existing parent.

    Raises:
        OSError: the file system cannot be queried.
    """
    p = Path(path).absolute()
    while not p.exists() and p.parent != p:
        p = p.parent
    return shutil.disk_usage(p).free


class DiskGuard:
    """The state of the disk holding ``path``: ``ok``, ``low`` or ``critical``.

    One ``statvfs`` call per :meth:`check` (a few microseconds), so calling it once a second costs
    nothing. To avoid a warning that flickers when the free space hovers at a threshold, a level is
    left only when the free space is back above its threshold by ``hysteresis_mb``.

    Args:
        path: a file or folder on the disk to watch (the data folder); it need not exist yet.
        warn_mb: below this many MiB free, :meth:`check` says ``low``.
        stop_mb: below this many MiB free it says ``critical``: stop recording. At most ``warn_mb``.
        hysteresis_mb: how far above a threshold the free space must climb to leave its level.
        free: how free bytes are measured (:func:`free_bytes`; tests give a fake).

    Attributes:
        level: the result of the last :meth:`check` (``ok`` before the first).
        free: bytes free at the last check; None before the first or when it failed.
        error: the OSError of the last check, None when it succeeded.

    Raises:
        ValueError: a threshold below 0, or ``stop_mb`` above ``warn_mb``.
    """

    def __init__(
        self,
        path: str | Path,
        warn_mb: float,
        stop_mb: float,
        *,
        hysteresis_mb: float = 16.0,
        free: Callable[[Path], int] = free_bytes,
    ):
        if min(warn_mb, stop_mb, hysteresis_mb) < 0:
            raise ValueError(f"disk thresholds must be at least 0 MiB, got {warn_mb}, {stop_mb}, {hysteresis_mb}")
        if stop_mb > warn_mb:
            raise ValueError(f"the stop threshold ({stop_mb} MiB) must not be above the warning one ({warn_mb} MiB)")
        self.path = Path(path)
        self.warn_bytes = round(warn_mb * MIB)
        self.stop_bytes = round(stop_mb * MIB)
        self.hysteresis_bytes = round(hysteresis_mb * MIB)
        self._free = free
        self.level: DiskLevel = "ok"
        self.free: int | None = None
        self.error: OSError | None = None

    def check(self) -> DiskLevel:
        """Measure the free space and return the level.

        A failed measurement (the folder vanished, an I/O error) is ``critical``: a recording that
        cannot tell whether it has room stops rather than risk a torn file. The error is kept in
        :attr:`error` for the log.
        """
        try:
            free = self._free(self.path)
        except OSError as exc:
            self.free, self.error, self.level = None, exc, "critical"
            return self.level
        self.free, self.error = free, None
        # Going down is immediate; coming back up past a threshold needs the margin above it.
        stop_at = self.stop_bytes + (self.hysteresis_bytes if self.level == "critical" else 0)
        warn_at = self.warn_bytes + (self.hysteresis_bytes if self.level != "ok" else 0)
        self.level = "critical" if free < stop_at else "low" if free < warn_at else "ok"
        return self.level

    @property
    def free_mb(self) -> float | None:
        """MiB free at the last check (None before the first or when it failed)."""
        return None if self.free is None else self.free / MIB

    def room(self) -> int | None:
        """Bytes that can still be recorded before the stop threshold, at the last check (None: unknown)."""
        return None if self.free is None else self.free - self.stop_bytes
