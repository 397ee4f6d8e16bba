"""The failed-login throttle, driven by an injected clock (no sleeps): waits double from the first over the
free count up to the cap, each count is separate, a stranger's failures never hold back an address that has
not failed, and memory stays bounded."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from gaitscope.sessions.accounts.throttle import LoginThrottle


class Clock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


def _throttle(clock: Clock, **kw: float) -> LoginThrottle:
    args = {"free": 3, "free_address": 10, "free_account": 10, "base_s": 1.0, "cap_s": 60.0, **kw}
    return LoginThrottle(clock=clock, **args)  # type: ignore[arg-type]


def test_an_address_failing_at_a_name_waits_doubling_up_to_the_cap() -> None:
    clock = Clock()
    t = _throttle(clock)
    waits = []
    for _ in range(12):
        waits.append(t.wait("10.0.0.9", "ada"))
        t.failed("10.0.0.9", "ada")
    assert waits[:3] == [0.0, 0.0, 0.0]  # the free failures
    assert t.wait("10.0.0.9", "ada") == 60.0  # 12 failures: 2**9 s, capped
    clock.t += 59.5
    assert t.wait("10.0.0.9", "ada") == pytest.approx(0.5)
    clock.t += 0.5
    assert t.wait("10.0.0.9", "ada") == 0.0


def test_the_waits_are_one_two_four_seconds() -> None:
    clock = Clock()
    t = _throttle(clock)
    for _ in range(3):
        t.failed("a", "ada")
    seen = []
    for _ in range(4):
        seen.append(t.wait("a", "ada"))
        clock.t += seen[-1]  # the guesser waits exactly as long as told, then fails again
        assert t.wait("a", "ada") == 0.0
        t.failed("a", "ada")
    assert seen == [1.0, 2.0, 4.0, 8.0]


def test_a_good_login_resets_the_pair_and_the_name_but_not_the_address() -> None:
    clock = Clock()
    t = _throttle(clock, free_address=4)
    for name in ("x1", "x2", "x3"):
        t.failed("a", name)
    t.failed("a", "ada")
    t.failed("a", "ada")
    t.failed("a", "ada")
    assert t.wait("a", "ada") == 4.0  # the pair's 3 failures: 1 s; the address's 6 (over 4 names): 4 s
    t.succeeded("a", "ada")
    assert t.wait("a", "ada") == 4.0  # the address still waits
    clock.t += 4.0
    assert t.wait("a", "ada") == 0.0
    t.failed("a", "ada")  # one more after the reset: the pair is at 1, the address at 7
    assert t.wait("a", "ada") == 8.0


def test_another_address_is_not_held_back_by_one_address_failures() -> None:
    clock = Clock()
    t = _throttle(clock)
    for _ in range(8):
        t.failed("stranger", "admin")
    assert t.wait("stranger", "admin") == 32.0
    assert t.wait("the-admins-desk", "admin") == 0.0


def test_the_name_count_holds_back_only_addresses_that_have_failed_at_it() -> None:
    clock = Clock()
    t = _throttle(clock, free_account=10)
    for i in range(10):  # one guess from each of 10 addresses
        t.failed(f"10.0.0.{i}", "admin")
    assert t.name_wait("admin") == 1.0
    assert t.wait("10.0.0.3", "admin") == 1.0  # a guesser's next guess waits for the name's count
    assert t.wait("10.0.0.200", "admin") == 0.0  # a fresh address is let try: the owner is never locked out
    t.failed("10.0.0.4", "admin")
    assert t.wait("10.0.0.5", "admin") == 2.0


def test_unknown_and_known_names_are_alike() -> None:
    """The throttle does not know which names exist: the same failures give the same waits."""
    clock = Clock()
    t = _throttle(clock)
    for _ in range(5):
        t.failed("a", "ada")
        t.failed("a", "nobody")
    assert t.wait("a", "ada") == t.wait("a", "nobody") == 4.0


def test_unlock_forgets_the_name_and_every_address_at_it() -> None:
    clock = Clock()
    t = _throttle(clock, free_account=4)
    for address in ("a", "b"):
        for _ in range(4):
            t.failed(address, "ada")
        t.failed(address, "eve")
    t.unlock("ada")
    assert t.wait("a", "ada") == t.wait("b", "ada") == t.name_wait("ada") == 0.0
    assert t.wait("a", "eve") == 0.0 and t._pairs.get(("a", "eve")) is not None  # other names untouched


def test_counts_are_forgotten_after_the_cap_and_the_tables_are_bounded() -> None:
    clock = Clock()
    t = _throttle(clock, max_entries=50)
    for i in range(500):
        t.failed(f"10.1.{i // 256}.{i % 256}", f"name{i}")
    assert len(t._pairs.counts) == len(t._addresses.counts) == len(t._names.counts) == 50
    clock.t += 61.0
    t.wait("x", "y")
    assert len(t._pairs.counts) == len(t._addresses.counts) == len(t._names.counts) == 0


@given(st.lists(st.tuples(st.sampled_from("abc"), st.sampled_from(["ada", "eve"]), st.floats(0, 100)), max_size=60))
def test_a_wait_is_within_the_cap_and_a_fresh_address_never_waits(events: list[tuple[str, str, float]]) -> None:
    clock = Clock()
    t = _throttle(clock)
    for address, name, dt in events:
        clock.t += dt
        w = t.wait(address, name)
        assert 0.0 <= w <= 60.0
        t.failed(address, name)
        assert 0.0 <= t.wait("fresh", name) <= 60.0
    assert t.wait("never-failed", "ada") == t.wait("never-failed", "eve") == 0.0  # a fresh address never waits


def test_bad_arguments_are_refused() -> None:
    with pytest.raises(ValueError, match="free counts"):
        LoginThrottle(free=0)
    with pytest.raises(ValueError, match="base_s"):
        LoginThrottle(base_s=10.0, cap_s=1.0)
