"""SessionHistory: the last 30 s of a session's states, bounded, and its seam with a new subscriber."""

from __future__ import annotations

import numpy as np

from gaitscope.sessions.live.subscribers import HISTORY_S, SessionHistory, Subscriber
from gaitscope.sessions.schema import GaitState


def _state(i: int, rate: float = 200.0, heel_strike: bool = False) -> GaitState:
    return GaitState(
        seq=i, t=i / rate, phase=0.5, phase_rate=1.0, stride_length_m=1.2, incline_deg=0.0, torque_Nm=1.0,
        tbe_phase=0.5, heel_strike=heel_strike, backup_reset=False, foot_angle_deg=None, shank_angle_deg=None,
        thigh_angle_deg=None, foot_pred_deg=0.0, shank_pred_deg=0.0, recv_ns=i,
    )  # fmt: skip


def test_keeps_only_the_last_30_s_at_its_decimation() -> None:
    h = SessionHistory(decimation=4, layout=[("phase_ekf", ("phase",))])
    for i in range(200 * 45):  # 45 s at 200 Hz
        h.offer(_state(i), [np.array([0.25])])
    t = [s.t for s in h.pending]
    assert t[-1] == (200 * 45 - 4) / 200 and t[-1] - t[0] <= HISTORY_S and t[-1] - t[0] > HISTORY_S - 0.05
    assert len(h.pending) == len(h.pending_outputs) == 1501  # 30 s at 50 Hz, both ends kept
    batches = h.batches(7, batch=400)
    assert [len(b.states) for b in batches] == [400, 400, 400, 301]
    assert batches[0].estimators["phase_ekf"].columns["phase"][:2] == [0.25, 0.25]
    assert len(h.pending) == 1501  # sending it keeps it


def test_is_bounded_by_samples_too_and_forgets_a_restarted_source() -> None:
    h = SessionHistory(decimation=1, capacity=100)
    for i in range(1000):
        h.offer(_state(i))
    assert len(h.pending) == 100
    h.offer(_state(3))  # time went back: a replay looping
    assert [s.t for s in h.pending] == [3 / 200]


def test_a_new_subscriber_continues_where_the_history_ends() -> None:
    h = SessionHistory(decimation=4)
    for i in range(10):  # kept: 0, 4, 8; then 9 offered
        h.offer(_state(i, heel_strike=i == 9))
    sub = Subscriber(decimation=4)
    h.seam(sub)
    for i in range(10, 20):
        sub.offer(_state(i))
    assert [s.seq for s in sub.pending] == [12, 16]
    assert sub.pending[0].heel_strike  # the strike at 9, between the two, is carried over
    fast = Subscriber(decimation=1)
    h.seam(fast)
    fast.offer(_state(10))
    assert [s.seq for s in fast.pending] == [10]
