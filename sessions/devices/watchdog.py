"""The torque watchdog: what torque a device applies, given the server's replies and the time since the last one.

Over a clinic's Wi-Fi a reply can come late or never. The device must then take the torque off the person
smoothly, on its own. :class:`TorqueWatchdog` is that rule, pure and clock-free (every call says what time it
is, in seconds on the device's monotonic clock), so it is the same in a test with a fake clock as on a device:

- **following**: each valid reply (a finite torque in ``[0, max_torque_Nm]``, of a frame newer than the last
  reply taken; an older one is out of order and ignored) sets the torque applied;
- **tripped**: when no valid reply has come for ``deadline_s``, the torque ramps from what was applied to zero
  at ``ramp_Nm_per_s`` and stays at zero; the reason is kept (:attr:`TorqueWatchdog.reason`). Replies that come
  now do not raise it again: a server that was slow is not trusted to still be in step with the person;
- **re-armed** only by :meth:`TorqueWatchdog.rearm`, which the client calls once the server has restarted its
  estimators on a new connection after a pause of at least ``MAX_GAP_S`` (the server's soft start then ramps the
  torque up from zero, as at the start of a session); until then it applies zero.

So whatever the replies and their timing, the torque applied is finite, within ``[0, max_torque_Nm]``, and zero
at the latest ``deadline_s + max_torque_Nm / ramp_Nm_per_s`` after the last valid reply
(``tests/sessions/devices/test_watchdog.py`` checks it over random fault timings).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final, Literal

__all__ = ["DEFAULT_RAMP_NM_PER_S", "TorqueWatchdog", "WatchdogConfig", "default_deadline_s"]

#: How fast a tripped watchdog takes the torque off (N m/s): 40 N m, the largest torque a session allows, in 0.4 s.
DEFAULT_RAMP_NM_PER_S: Final = 100.0
#: The deadline is this many sample periods of the session's rate, and at least :data:`MIN_DEADLINE_S`.
DEADLINE_PERIODS: Final = 10
MIN_DEADLINE_S: Final = 0.05

State = Literal["waiting", "following", "tripped"]


def default_deadline_s(rate_hz: float) -> float:
    """The default deadline for a session's rate: 10 sample periods, at least 50 ms (200 Hz: 50 ms; 50 Hz: 0.2 s)."""
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz must be a number > 0, got {rate_hz}")
    return max(DEADLINE_PERIODS / rate_hz, MIN_DEADLINE_S)


@dataclass(frozen=True)
class WatchdogConfig:
    """Attributes:
    deadline_s: longest wait for a valid reply before the torque comes off (s).
    ramp_Nm_per_s: how fast it comes off (N m/s).
    max_torque_Nm: the device's own limit; a reply above it is not valid.
    """

    deadline_s: float
    ramp_Nm_per_s: float = DEFAULT_RAMP_NM_PER_S
    max_torque_Nm: float = 80.0

    def __post_init__(self) -> None:
        for name in ("deadline_s", "ramp_Nm_per_s", "max_torque_Nm"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a number > 0, got {v}")


class TorqueWatchdog:
    """See the module docstring. Starts ``waiting`` (zero) until :meth:`rearm`.

    Attributes:
        state: ``waiting`` (zero, until re-armed), ``following`` the replies, or ``tripped`` (ramping to zero).
        reason: why it last tripped (None: never).
    """

    def __init__(self, config: WatchdogConfig):
        self.config = config
        self.state: State = "waiting"
        self.reason: str | None = None
        self._torque = 0.0  # what was applied at _t
        self._t = -math.inf  # time of the last valid reply (following) or of the trip (tripped)
        self._seq = -1  # the newest reply's frame taken

    def rearm(self, now: float) -> None:
        """Follow replies again (zero until the first one comes); the client calls it on a new connection that
        the server starts from its soft start (see the module docstring)."""
        self.state, self._torque, self._t, self._seq = "following", 0.0, now, -1

    def reply(self, now: float, seq: int, torque_Nm: float) -> bool:
        """A reply arrived at ``now``; whether it was taken (valid, in order, while following in time)."""
        self.output(now)  # trips first if the deadline passed before this reply came
        if self.state != "following" or seq <= self._seq:
            return False
        if not (math.isfinite(torque_Nm) and 0.0 <= torque_Nm <= self.config.max_torque_Nm):
            return False
        self._seq, self._torque, self._t = seq, float(torque_Nm), now
        return True

    def trip(self, now: float, reason: str) -> None:
        """Take the torque off from ``now`` (the client calls it when the socket closes, say)."""
        if self.state == "following":
            self._torque = self._applied(now)
            self.state, self._t, self.reason = "tripped", now, reason

    def output(self, now: float) -> float:
        """The torque to apply at ``now`` (N m): finite, within ``[0, max_torque_Nm]``."""
        if self.state == "following" and now - self._t > self.config.deadline_s:
            due = self._t + self.config.deadline_s
            late = "no reply yet" if self._seq < 0 else f"no valid reply for {1000 * (now - self._t):.0f} ms"
            self.trip(due, f"{late} (deadline {1000 * self.config.deadline_s:.0f} ms)")
        return self._applied(now)

    def _applied(self, now: float) -> float:
        if self.state == "waiting":
            return 0.0
        if self.state == "following":
            return self._torque
        return max(0.0, self._torque - self.config.ramp_Nm_per_s * max(0.0, now - self._t))
