"""A running session's data health (:class:`~gaitscope.sessions.schema.Health`), sent to its browsers once a
second: the rate and latency of the last second, samples and drops, faults, the primary's tracking, and each
extension's part (the disk, the IMUs)."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any, Final

import numpy as np

from gaitscope.sessions import schema
from gaitscope.sessions.estimation import FrameEstimator
from gaitscope.sessions.live.sources import LiveDevice
from gaitscope.sessions.live.subscribers import Subscriber

if TYPE_CHECKING:
    from gaitscope.sessions.live.runtime import SessionRuntime

__all__ = ["LOST_SHOWN_S", "health"]

#: Data health says the primary lost track for this long after it did (s).
LOST_SHOWN_S: Final = 5.0


def health(rt: SessionRuntime, sub: Subscriber | None = None) -> schema.Health:
    """``rt``'s data health now, as ``sub`` (its dropped messages) sees it."""
    now = time.time_ns()
    recent = [r for r in rt.recent_recv if now - r < 1_000_000_000]
    lat = np.array(list(rt.recent_latency)[-len(recent) :]) if recent else np.array([])
    dropped_input = rt.dropped_input + (rt.source.dropped if isinstance(rt.source, LiveDevice) else 0)
    return schema.Health(
        session_id=rt.session.id,
        rate_hz=float(len(recent)),
        latency_ms_p50=float(np.percentile(lat, 50)) if lat.size else None,
        latency_ms_p95=float(np.percentile(lat, 95)) if lat.size else None,
        samples=rt.samples,
        dropped_input=dropped_input,
        dropped_client=sub.dropped if sub is not None else 0,
        clients=len(rt.subscribers),
        implausible=rt.estimator.implausible,
        faults=rt.estimator.faults + rt.torque_faults,
        estimators=list(rt.estimator.stack.names),
        primary=rt.estimator.primary,
        failed_estimators=dict(rt.estimator.stack.failed),
        **_tracking(rt.estimator),
        **{k: v for extension in rt.extensions for k, v in extension.health().items()},
    )


def _tracking(estimator: FrameEstimator) -> dict[str, Any]:
    """The primary's tracking for data health: standing, lost in the last ``LOST_SHOWN_S``, walking."""
    e, lost = estimator.last, estimator.last_lost
    if e is None or e.primary is None:
        return {}
    if lost is not None and estimator.last_t - lost[0] <= LOST_SHOWN_S:
        return {"tracking": "lost", "tracking_note": lost[1]}
    return {"tracking": "standing" if e.standing else "walking"}
