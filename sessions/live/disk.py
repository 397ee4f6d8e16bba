"""Free space on the recordings' disk, checked against two thresholds: warn, then stop.

A 200 Hz session writes about 29 KiB/s (~100 MiB an hour) of MCAP; an hour's index adds ~1 MiB at
:meth:`~sessions.formats.recording.Recorder.finish`, and crash recovery writes a full copy of the file
beside it before it replaces the original. The runtime calls :meth:`DiskGuard.check` once a
second: ``low`` warns the clinician, ``critical`` stops the recording cleanly while there is still
room to finish it, so a full disk (:class:`~sessions.formats.recording.RecordingError`) stays the exception.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Final, Literal

__all__ = ["MIB", "DiskGuard", "DiskLevel", "free_bytes"]

MIB: Final = 1024 * 1024

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
