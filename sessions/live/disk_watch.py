"""A session's watch on its recording's disk, as a session extension.

Once a second (:meth:`DiskWatch.on_tick`) the disk guard's state is read (:mod:`gaitscope.sessions.live.disk`):
``low`` is one system event saying how many minutes of this session's recording are left at its own rate,
``critical`` ends the session cleanly (recording finished) while there is still room to finish it. Data
health shows the state and the minutes left.
"""

from __future__ import annotations

import asyncio
import contextlib
from typing import TYPE_CHECKING, Any

from gaitscope.sessions.errors import FREE_SPACE_HINT
from gaitscope.sessions.live.disk import DiskLevel, GrowthRate, estimated_bytes_per_s, minutes
from gaitscope.sessions.live.extensions import SessionExtension

if TYPE_CHECKING:
    from gaitscope.sessions.live.runtime import SessionRuntime

__all__ = ["DiskWatch"]


class DiskWatch(SessionExtension):
    """The disk of one session's recording.

    Args:
        runtime: the session; its ``disk_check`` (the disk's state: ``ok``, ``low``, ``critical``; None: not
            watched) and ``disk_room`` (bytes that can still be recorded before the disk guard stops; None:
            unknown) are read at each check.

    Attributes:
        state: the state at the last check.
        rate: this session's recording rate (bytes/s): estimated from its channels, rate and stack, then measured.
        minutes: minutes of recording left at that rate before the disk guard stops it (None: unknown).
    """

    def __init__(self, runtime: SessionRuntime):
        self.rt = runtime
        self.state: DiskLevel = "ok"
        declared = getattr(runtime.source, "channels", None)
        n_channels = None if declared is None else len(declared)
        n_estimators = len(runtime.estimator.stack.names)
        self.rate = GrowthRate(estimated_bytes_per_s(1.0 / runtime.sample_period, n_channels, n_estimators))
        self.minutes: float | None = None

    def on_tick(self) -> None:
        self.check()

    def health(self) -> dict[str, Any]:
        return {"disk": self.state, "disk_minutes": self.minutes}

    def check(self) -> DiskLevel:
        """Look at the disk; warn once when low, stop cleanly when critical; say what is left as minutes of this
        session's recording (:attr:`minutes`, data health)."""
        rt = self.rt
        if rt.disk_check is None:
            return "ok"
        state = rt.disk_check()
        if rt.recorder is not None:
            with contextlib.suppress(OSError):
                self.rate.update(rt.recorder.path.stat().st_size, rt.clock())
        room = rt.disk_room() if rt.disk_room is not None else None
        self.minutes = None if room is None else round(minutes(room, self.rate.bytes_per_s), 1)
        if state != self.state:
            if state == "low":
                left = "" if self.minutes is None else f"about {self.minutes:.0f} min of recording left "
                rt.event("system", f"disk space is low: {left}at this session's {self._rate_text()}; the recording "
                         f"stops when it runs out; {FREE_SPACE_HINT}")  # fmt: skip
            elif state == "critical" and rt.ended is None:
                asyncio.get_running_loop().create_task(
                    rt.end("stopped", "the disk is almost full: recording finished and session stopped")
                )
        self.state = state
        return state

    def _rate_text(self) -> str:
        """This session's recording rate in words: "305 kB/s (74 channels at 200 Hz, 6 estimators)"."""
        channels = getattr(self.rt.source, "channels", None)
        what = "undeclared channels" if channels is None else f"{len(channels)} channels"
        return (f"{self.rate.bytes_per_s / 1000:.0f} kB/s ({what} at {1.0 / self.rt.sample_period:g} Hz, "
                f"{len(self.rt.estimator.stack.names)} estimators)")  # fmt: skip
