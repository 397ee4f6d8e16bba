"""The torque watchdog over random fault timings: the torque applied is always finite and within the device's
limit, zero within the deadline plus the ramp after the last valid reply, never raised again once tripped, and
follows the replies while they come in time."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitscope.sessions.devices.watchdog import TorqueWatchdog, WatchdogConfig, default_deadline_s

CONFIG = WatchdogConfig(deadline_s=0.05, ramp_Nm_per_s=100.0, max_torque_Nm=40.0)
_TORQUES = st.one_of(
    st.floats(0.0, 40.0), st.floats(-1e9, 1e9), st.sampled_from([math.nan, math.inf, -math.inf, 40.0001])
)
#: A reply: how long after the last event it comes (s), its seq step (negative: out of order), its torque.
_REPLIES = st.lists(st.tuples(st.floats(0.0, 0.3), st.integers(-3, 3), _TORQUES), max_size=80)


@settings(max_examples=300, deadline=None)
@given(_REPLIES, st.floats(0.0, 1.0))
def test_whatever_the_replies_the_torque_is_bounded_and_off_in_time(replies: list, tail_s: float) -> None:
    w = TorqueWatchdog(CONFIG)
    now, seq, last_valid = 0.0, 0, 0.0
    w.rearm(now)
    tripped_at: float | None = None
    prev_out, prev_t = 0.0, 0.0
    for gap, step, torque in replies:
        # sample the output between replies: bounded, and never rising once tripped
        for k in range(1, 4):
            t = now + gap * k / 4
            out = w.output(t)
            assert math.isfinite(out) and 0.0 <= out <= CONFIG.max_torque_Nm
            if t - last_valid > CONFIG.deadline_s + CONFIG.max_torque_Nm / CONFIG.ramp_Nm_per_s:
                assert out == 0.0
            if w.state == "tripped":
                if tripped_at is not None:
                    assert out <= prev_out + 1e-12
                    assert prev_out - out <= CONFIG.ramp_Nm_per_s * (t - prev_t) + 1e-9  # smooth: the ramp's rate
                tripped_at = tripped_at if tripped_at is not None else t
            prev_out, prev_t = out, t
        now += gap
        seq += step
        if w.reply(now, seq, torque):
            assert 0.0 <= torque <= CONFIG.max_torque_Nm and w.output(now) == torque
            last_valid = now
            prev_out, prev_t = torque, now
        elif w.state == "tripped":
            assert tripped_at is not None or w.output(now) <= prev_out
    end = now + tail_s
    off_by = last_valid + CONFIG.deadline_s + CONFIG.max_torque_Nm / CONFIG.ramp_Nm_per_s
    if end >= off_by:
        assert w.output(end) == 0.0


def test_a_late_reply_trips_it_and_the_torque_ramps_off_at_its_rate() -> None:
    w = TorqueWatchdog(CONFIG)
    w.rearm(0.0)
    assert w.reply(0.01, 1, 30.0) and w.output(0.05) == 30.0
    assert w.output(0.06) == 30.0 and w.state == "following"  # exactly at the deadline: still in time
    assert w.output(0.16) == pytest.approx(30.0 - 100.0 * 0.1)  # 0.1 s after the deadline (0.06)
    assert w.state == "tripped" and w.reason is not None and "no valid reply for" in w.reason
    assert not w.reply(0.17, 2, 35.0)  # a reply now does not raise it again
    assert w.output(0.40) == 0.0
    w.rearm(1.5)  # a new connection after the server's pause: zero until the first reply
    assert w.output(1.5) == 0.0 and w.reply(1.51, 1, 2.0) and w.output(1.52) == 2.0


def test_out_of_order_and_invalid_replies_are_not_taken() -> None:
    w = TorqueWatchdog(CONFIG)
    assert w.output(0.0) == 0.0 and not w.reply(0.0, 1, 5.0)  # waiting: nothing taken before rearm
    w.rearm(0.0)
    assert w.reply(0.01, 5, 10.0)
    assert not w.reply(0.02, 4, 20.0)  # an older frame's reply
    assert not w.reply(0.02, 6, math.nan) and not w.reply(0.02, 6, -1.0) and not w.reply(0.02, 6, 41.0)
    assert w.output(0.02) == 10.0
    w.trip(0.03, "the socket closed")
    assert w.reason == "the socket closed" and w.output(0.08) == pytest.approx(5.0)


@pytest.mark.parametrize(("rate", "deadline"), [(200.0, 0.05), (100.0, 0.1), (50.0, 0.2), (1000.0, 0.05)])
def test_the_default_deadline_is_ten_periods_and_at_least_50_ms(rate: float, deadline: float) -> None:
    assert default_deadline_s(rate) == pytest.approx(deadline)


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, math.inf])
def test_a_config_that_makes_no_sense_is_refused(bad: float) -> None:
    with pytest.raises(ValueError):
        WatchdogConfig(deadline_s=bad)
    with pytest.raises(ValueError):
        default_deadline_s(bad)


def test_the_client_imports_nothing_of_the_server() -> None:
    import subprocess
    import sys

    code = (
        "import sys, gaitscope.sessions.devices.client; "
        "print(','.join(m for m in ('fastapi', 'numpy', 'pydantic', 'sqlalchemy', 'starlette', 'uvicorn', 'scipy') "
        "if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""  # a device's controller installs websockets, not the server's stack
