"""Strangers guessing passwords never stall a patient's torque (a real server with accounts on, real sockets).

Reproduces issue 21 (01eb3ed, a 2-core machine): 16 anonymous clients guessing passwords made a steady
200 Hz device's reply take 3.2-3.8 s and a clinician's GET 1.5-2.4 s (median): every login hashed inside a
write transaction (``BEGIN IMMEDIATE``), so the logins were one at a time and any other write (here a
clinician's annotation of the session, made on the event loop at 01eb3ed) waited behind the queue of them,
holding up the loop and every device's torque with it. Now a login's hash runs outside any
transaction, one at a time in threads of their own (:meth:`~gaitscope.sessions.accounts.Accounts.login_async`),
and failed logins are throttled (:mod:`gaitscope.sessions.accounts.throttle`).

The guessers run in a process of their own, so that their requests are not made with this process's
interpreter, which times the device.
"""

from __future__ import annotations

import asyncio
import io
import json
import math
import multiprocessing
import os
import random
import statistics
import sys
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import pytest

from gaitscope.server.bench.launch import RunningServer, start_server
from gaitscope.server.cli import main
from gaitscope.sessions.synth.trials import replay_input, sensor_trial
from tests.load import p95, steady

#: A real server over real sockets: seconds per test, and timing depends on the machine's load.
pytestmark = pytest.mark.slow

RATE = 200.0  # the steady device's rate (Hz)
QUIET_S = 3.0  # seconds it is timed alone
FLOOD_S = 6.0  # seconds it is timed beside the guessers
GUESSERS = 16
PASSWORD = "the clinic's good password"


def _walk() -> tuple[list[str], list[dict[str, float]]]:
    """A device's channels and frames of a walk (what ``gaitscope loadbench`` sends: its intent onsets are
    stored as events by the session, on the event loop at 01eb3ed)."""
    sensors, _, _ = sensor_trial([(1.2, 0.0, 40)], rate_hz=RATE)
    data = replay_input(sensors)
    signals = dict(data.signals)
    return list(signals), [{k: float(v[i]) for k, v in signals.items()} for i in range(len(data.time_s))]


def _request(
    base: str, method: str, path: str, body: object = None, headers: dict[str, str] | None = None
) -> tuple[int, dict[str, str], bytes]:
    data = None if body is None else json.dumps(body).encode()
    all_headers = {"Content-Type": "application/json", **(headers or {})}
    req = urllib.request.Request(f"{base}{path}", data, all_headers, method=method)
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, dict(r.headers), r.read()
    except urllib.error.HTTPError as e:
        return e.code, dict(e.headers), e.read()


def _login(base: str, name: str) -> dict[str, str]:
    status, headers, body = _request(base, "POST", "/api/auth/login", {"name": name, "password": PASSWORD})
    assert status == 200, body
    cookie = headers["set-cookie"].split(";")[0]
    return {"Cookie": cookie, "X-CSRF-Token": json.loads(body)["csrf_token"]}


def _guess(base: str, seconds: float, seed: int, started: Any) -> list[int]:
    """One anonymous guesser: logins with invented names (and now and then a real one) and wrong passwords,
    one after another for ``seconds``; the statuses it got."""
    rnd = random.Random(seed)
    statuses = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        name = rnd.choice(["admin", "clinician", f"user{rnd.randrange(10**6)}", f"guess{rnd.randrange(10**6)}"])
        statuses.append(_request(base, "POST", "/api/auth/login", {"name": name, "password": f"pw{rnd.random()}"})[0])
        started.set()
    return statuses


def _flood(base: str, seconds: float, out: multiprocessing.Queue, started: Any) -> None:
    """The guessers, in a process of their own; ``started`` is set once a guess was answered."""
    with ThreadPoolExecutor(GUESSERS) as pool:
        done = list(pool.map(lambda i: _guess(base, seconds, i, started), range(GUESSERS)))
    out.put([s for statuses in done for s in statuses])


def _frames(frames: list[dict[str, float]]) -> Callable[[int, float], str]:
    """The steady device's frame ``k`` at time ``t``: the walk's frames over and over."""
    return lambda k, t: json.dumps({"type": "frame", **frames[k % len(frames)], "seq": k, "t": t})


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningServer]:
    data = tmp_path_factory.mktemp("flood")
    for name, role in (("admin", "admin"), ("clinician", "clinician")):
        sys.stdin, saved = io.StringIO(PASSWORD + "\n"), sys.stdin
        try:
            assert main(["user", "--data-dir", str(data), "add", name, "--role", role, "--password-stdin"]) == 0
        finally:
            sys.stdin = saved
    env = {**os.environ, "GAITSCOPE_AUTH": "true"}
    server = start_server(data, "--no-leg-view", "--no-demo", env=env)
    yield server
    server.stop()


def test_a_login_flood_does_not_stall_a_device_or_a_clinician(server: RunningServer) -> None:
    base = server.base
    admin = _login(base, "admin")
    _, _, subject = _request(base, "POST", "/api/subjects", {"code": "F01", "leg_length_m": 0.9, "mass_kg": 70}, admin)
    channels, frames = _walk()
    device = {"kind": "device", "rate_hz": RATE, "channels": channels}
    body = {"subject_id": json.loads(subject)["id"], "source": device}
    status, _, session = _request(base, "POST", "/api/sessions", body, admin)
    assert status == 201, session
    sid = int(json.loads(session)["id"])
    status, _, issued = _request(base, "POST", f"/api/sessions/{sid}/device-tokens", {}, admin)
    assert status == 201, issued
    token = json.loads(issued)["token"]
    clinician = _login(base, "clinician")

    alone = asyncio.run(steady(server.port, sid, token, QUIET_S, RATE, _frames(frames), reply_timeout=10.0))
    assert len(alone.rtts) == alone.sent >= 0.8 * QUIET_S * RATE
    quiet = p95(alone.rtts)

    gets: list[float] = []
    notes: list[float] = []
    stop = threading.Event()

    def clinician_works() -> None:
        """Reads the subjects every 0.1 s, and marks the session (an annotation: a write) every half second."""
        k = 0
        while not stop.wait(0.1):
            t0 = time.monotonic()
            status, _, _ = _request(base, "GET", "/api/subjects", headers=clinician)
            assert status == 200
            gets.append(time.monotonic() - t0)
            k += 1
            if k % 5 == 0:
                t0 = time.monotonic()
                note = {"text": f"mark {k // 5}"}
                status, _, _ = _request(base, "POST", f"/api/sessions/{sid}/annotations", note, clinician)
                assert status == 201
                notes.append(time.monotonic() - t0)

    spawn = multiprocessing.get_context("spawn")
    out, started = spawn.Queue(), spawn.Event()
    flood = spawn.Process(target=_flood, args=(base, FLOOD_S + 1.5, out, started))
    flood.start()
    reader = threading.Thread(target=clinician_works)
    try:
        assert started.wait(60), "the guessers did not start"  # the guessers are at it
        reader.start()
        loaded_run = asyncio.run(steady(server.port, sid, token, FLOOD_S, RATE, _frames(frames), reply_timeout=10.0))
        sent, rtts = loaded_run.sent, loaded_run.rtts
    finally:
        stop.set()
        statuses = out.get(timeout=120)
        flood.join(timeout=30)
        if reader.is_alive():
            reader.join(timeout=30)
    loaded = p95(rtts) if rtts else math.inf
    median_get = statistics.median(gets) if gets else math.inf
    print(
        f"device alone p95 {quiet * 1e3:.1f} ms; beside {GUESSERS} guessers ({len(statuses)} logins refused in"
        f" {FLOOD_S + 1.5:g} s): {len(rtts)}/{sent} replies, p95 {loaded * 1e3:.1f} ms, max {max(rtts) * 1e3:.0f} ms;"
        f" clinician GET median {median_get * 1e3:.0f} ms, max {max(gets) * 1e3:.0f} ms ({len(gets)}),"
        f" annotations {', '.join(f'{n * 1e3:.0f}' for n in notes)} ms"
    )
    assert len(statuses) >= GUESSERS and set(statuses) == {401}  # they guessed, and were refused
    assert len(rtts) == sent >= 0.5 * FLOOD_S * RATE  # every frame answered (sent one at a time)
    # On a loaded 2-core machine the guessers' hashing takes CPU from the loop: a generous bound, far below
    # the 3.2-3.8 s of 01eb3ed.
    assert loaded <= max(3 * quiet, quiet + 0.100), (quiet, loaded)
    assert median_get <= 0.300 and max(gets) <= 1.0, (median_get, max(gets))
    assert len(notes) >= FLOOD_S and max(notes) <= 1.0, notes  # a clinician's change waits for no guesser
