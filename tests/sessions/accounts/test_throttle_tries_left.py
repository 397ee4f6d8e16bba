"""``LoginThrottle.tries_left``: the failed logins an address may still make at a name before it waits
(issue #23, 9), the least of its three counts, on an injected clock."""

from __future__ import annotations

from gaitscope.sessions.accounts import LoginThrottle


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_tries_left_counts_down_to_the_wait_and_back_after_it() -> None:
    clock = Clock()
    throttle = LoginThrottle(free=3, free_address=5, free_account=4, base_s=1.0, cap_s=60.0, clock=clock)
    assert throttle.tries_left("a", "ada") == 3
    left = []
    for _ in range(3):
        throttle.failed("a", "ada")
        left.append(throttle.tries_left("a", "ada"))
    assert left == [2, 1, 0] and throttle.wait("a", "ada") == 1.0
    assert throttle.tries_left("a", "nobody") == 2  # the address's count: 5 - 3, whatever the name
    throttle.failed("b", "ada")  # another address at the name: the name's count, 4 - 4, binds b only
    assert throttle.tries_left("b", "ada") == 0 and throttle.tries_left("c", "ada") == 3
    clock.t = 61.0  # forgotten cap_s after the last failure
    assert throttle.tries_left("a", "ada") == 3


def test_a_good_login_gives_the_tries_back_but_not_the_addresss() -> None:
    throttle = LoginThrottle(free=3, free_address=4, free_account=10, clock=Clock())
    throttle.failed("a", "ada")
    throttle.failed("a", "ada")
    throttle.succeeded("a", "ada")
    assert throttle.tries_left("a", "ada") == 2  # the pair's 3 again; the address's 4 - 2 binds
