"""``gaitscope loadbench``: N live devices at 200 Hz, M browser clients each, over loopback.

Starts a real server (``gaitscope serve`` in a subprocess, no demo, no leg view), creates N sessions
with a live-device source, and from worker processes (one for the devices, two for the browsers, each
on uvloop) runs N device clients that push simulated sensor
frames at the given rate (each stamped with ``sent_ns``) and read their torque commands, plus M
browser clients per session that take the full-rate stream (``max_rate_hz=0``, ``batch_ms`` as the UI).
Device-to-browser latency = browser receive time - ``sent_ns`` (one machine, one clock). Server CPU
and memory are read from ``/proc``. The same run first measures one device with one client as the
baseline the loaded numbers are compared with.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import multiprocessing
import os
import tempfile
import time
import urllib.request
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gaitscope.estimators.gp_ekf_estimator import GPEKFEstimator
from gaitscope.estimators.protocol import HEEL_STRIKE
from gaitscope.server.bench.launch import start_server
from gaitscope.sessions.formats.models import default_model_path, load_model
from gaitscope.sessions.registry import StackContext, resolve
from gaitscope.sessions.synth.trials import replay_input, sensor_trial

#: What a device adds for the GP-EKF (``--gp-ekf``): joint encoders and its heel-strike sensor.
GP_EKF_CHANNELS = (*GPEKFEstimator.inputs, HEEL_STRIKE)

TARGET_P95_MS = 50.0


@dataclass
class Stream:
    """What one browser client saw of one session."""

    latencies_ms: list[float] = field(default_factory=list)
    received: int = 0
    dropped_client: int = 0
    dropped_input: int = 0
    first: float | None = None
    last: float | None = None

    @property
    def rate_hz(self) -> float:
        if self.first is None or self.last is None or self.last <= self.first:
            return 0.0
        return self.received / (self.last - self.first)


def _post(base: str, path: str, body: dict[str, object]) -> dict[str, object]:
    req = urllib.request.Request(
        base + path, data=json.dumps(body).encode(), headers={"Content-Type": "application/json"}, method="POST"
    )
    with urllib.request.urlopen(req, timeout=10) as r:
        return json.loads(r.read())


def _tree(pid: int) -> list[int]:
    """``pid`` and its descendants now (a cluster's supervisor: its nodes, nginx, their GP workers)."""
    parents: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue  # ended meanwhile
        parents.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    found, todo = [], [pid]
    while todo:
        found.append(p := todo.pop())
        todo += parents.get(p, [])
    return found


def _proc_cpu_s(pid: int) -> float:
    """CPU seconds of ``pid`` and its descendants (user + system)."""
    total = 0.0
    for p in _tree(pid):
        with contextlib.suppress(OSError):
            fields = Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[1].split()
            total += (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    return total


def _proc_mem_mb(pid: int) -> tuple[float, float]:
    """Resident and peak resident MB of ``pid`` and its descendants, summed."""
    rss = peak = 0.0
    for p in _tree(pid):
        with contextlib.suppress(OSError, KeyError):
            lines = Path(f"/proc/{p}/status").read_text().splitlines()
            status = dict(line.split(":", 1) for line in lines if ":" in line)
            rss += int(status["VmRSS"].split()[0]) / 1024
            peak += int(status["VmHWM"].split()[0]) / 1024
    return rss, peak


async def _device(
    ws_base: str, session_id: int, token: str, frames: list[dict[str, object]], rate: float, stop_wall: float
) -> int:
    import websockets

    sent = 0
    async with websockets.connect(f"{ws_base}/ws/devices/{session_id}?token={token}", max_queue=None) as ws:

        async def replies() -> None:
            async for _ in ws:
                pass

        reader = asyncio.create_task(replies())
        loop = asyncio.get_running_loop()
        start = loop.time()
        stop = start + (stop_wall - time.time())
        k = 0
        while loop.time() < stop:
            due = start + k / rate
            if due > loop.time():
                await asyncio.sleep(due - loop.time())
            f = dict(frames[k % len(frames)])
            f.update(seq=k, t=k / rate, sent_ns=time.time_ns())
            await ws.send(json.dumps(f))
            sent += 1
            k += 1
        await asyncio.sleep(0.3)
        reader.cancel()
    return sent


async def _browser(ws_base: str, session_id: int, batch_ms: float, stop_wall: float, warmup_wall: float) -> Stream:
    import websockets

    out = Stream()
    loop = asyncio.get_running_loop()
    stop = loop.time() + (stop_wall - time.time())
    warmup = loop.time() + (warmup_wall - time.time())
    url = f"{ws_base}/ws/sessions/{session_id}?max_rate_hz=0&batch_ms={batch_ms}"
    async with websockets.connect(url, max_size=None) as ws:
        while loop.time() < stop + 0.2:
            try:
                text = await asyncio.wait_for(ws.recv(), timeout=max(stop + 0.2 - loop.time(), 0.01))
            except TimeoutError:
                break
            now_ns = time.time_ns()
            msg = json.loads(text)
            if msg["type"] == "states" and loop.time() > warmup:
                out.received += len(msg["states"])
                out.first = out.first or loop.time()
                out.last = loop.time()
                out.latencies_ms += [(now_ns - s["sent_ns"]) / 1e6 for s in msg["states"] if s["sent_ns"]]
            elif msg["type"] == "health":
                out.dropped_client, out.dropped_input = msg["dropped_client"], msg["dropped_input"]
    return out


@dataclass(frozen=True)
class _Job:
    """Work of one load-generating process."""

    kind: str  # "devices" or "browsers"
    ws_base: str
    ids: list[int]
    rate: float
    batch_ms: float
    warmup_wall: float
    stop_wall: float
    frames: list[dict[str, object]] = field(default_factory=list)
    tokens: dict[int, str] = field(default_factory=dict)  # the devices' tokens, by session id


def _worker(job: _Job) -> tuple[list[int] | list[Stream], float]:
    """One load-generating process: all the devices, or a share of the browser clients (uvloop); with
    the CPU seconds it used."""
    import uvloop

    cpu0 = time.process_time()

    async def devices() -> list[int]:
        return list(
            await asyncio.gather(
                *(_device(job.ws_base, i, job.tokens[i], job.frames, job.rate, job.stop_wall) for i in job.ids)
            )
        )

    async def browsers() -> list[Stream]:
        return list(
            await asyncio.gather(
                *(_browser(job.ws_base, i, job.batch_ms, job.stop_wall, job.warmup_wall) for i in job.ids)
            )
        )

    done = uvloop.run(devices()) if job.kind == "devices" else uvloop.run(browsers())
    return done, time.process_time() - cpu0


def device_frames(rate: float, gp_ekf: bool = False) -> list[dict[str, object]]:
    """A simulated device's frames (40 s of walking at 1.2 m/s, ``rate`` Hz) without ``seq``, ``t``, ``sent_ns``:
    the IMU-derived angles the default stack reads, and with ``gp_ekf`` the joint encoders and heel strikes."""
    sensors, _, _ = sensor_trial([(1.2, 0.0, 40)], rate_hz=rate)
    data = replay_input(sensors)
    signals = dict(data.signals)
    if gp_ekf:
        signals |= {c: sensors[c].to_numpy(np.float64) for c in GP_EKF_CHANNELS}
    return [{"type": "frame", **{k: float(v[i]) for k, v in signals.items()}} for i in range(len(data.time_s))]


def _run(
    base: str, sessions: int, clients: int, rate: float, seconds: float, batch_ms: float, gp_ekf: bool = False
) -> dict:
    """Devices in one process, browser clients spread over two more, so the load generator is not the
    bottleneck it would be in a single Python process. ``gp_ekf``: the devices also send joint encoders and
    heel strikes, and every session runs the GP-EKF (seed 003, opt-in) beside its default stack, learning."""
    ws_base = base.replace("http://", "ws://")
    frames = device_frames(rate, gp_ekf)
    signals = {k: np.zeros(1) for k in frames[0] if k != "type"}  # the channels the device sends
    subject = _post(base, "/api/subjects", {"code": f"LB{time.time_ns() % 10**8}", "leg_length_m": 0.9, "mass_kg": 70})
    # the device declares what it sends, as a real one should: its sessions run the estimators those feed
    device = {"kind": "device", "rate_hz": rate, "channels": list(signals)}
    body: dict[str, object] = {"subject_id": subject["id"], "source": device}
    if gp_ekf:
        # the stack the server would choose for these channels (the registry's own rule), and the GP-EKF
        built = StackContext(load_model(default_model_path())[0], 0.9, 70.0, 1.0 / rate)
        stack = [e.name for e in resolve(None, signals, built)]
        body["settings"] = {"estimators": [*stack, "gp_ekf"]}
    ids = [int(_post(base, "/api/sessions", body)["id"]) for _ in range(sessions)]  # type: ignore[call-overload]
    # each device with its session's token, as a real one connects
    tokens = {i: str(_post(base, f"/api/sessions/{i}/device-tokens", {})["token"]) for i in ids}
    now = time.time()
    browser_ids = [i for i in ids for _ in range(clients)]
    shares = [browser_ids[k::2] for k in range(2)] if len(browser_ids) > 1 else [browser_ids]
    jobs = [_Job("browsers", ws_base, share, rate, batch_ms, now + 3.0, now + 3.0 + seconds) for share in shares]
    jobs.append(_Job("devices", ws_base, ids, rate, batch_ms, now + 3.0, now + 3.0 + seconds, frames, tokens))
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=len(jobs), mp_context=ctx) as pool:
        t0 = time.monotonic()
        done = list(pool.map(_worker, jobs))
        wall = time.monotonic() - t0
    trained = []  # GP-EKF models each session trained and installed (its versions but the population one)
    if gp_ekf:
        for i in ids:
            with urllib.request.urlopen(f"{base}/api/sessions/{i}/gp-learning", timeout=10) as r:
                trained.append(len(json.loads(r.read())["versions"]) - 1)
    for i in ids:
        _post(base, f"/api/sessions/{i}/stop", {})
    results = [r for r, _ in done]
    streams = [s for r in results[:-1] for s in r if isinstance(s, Stream)]
    generator_cpu = 100.0 * sum(cpu for _, cpu in done) / wall
    return {"sent": results[-1], "streams": streams, "generator_cpu_pct": generator_cpu, "gp_trained": trained}


def _percentile(values: np.ndarray, q: float) -> float:
    """The ``q``-th percentile, NaN when there is no value (a load where no stream got a sample)."""
    return float(np.percentile(values, q)) if values.size else math.nan


def _summary(label: str, result: dict, cpu_s: float, wall_s: float, mem: tuple[float, float]) -> dict[str, float]:
    streams: list[Stream] = result["streams"]
    lat = np.concatenate([np.asarray(s.latencies_ms, dtype=np.float64) for s in streams] or [np.zeros(0)])
    rates = [s.rate_hz for s in streams]
    empty = sum(1 for s in streams if not s.latencies_ms)  # a stream that got no sample: reported, not a crash
    out = {
        "streams": float(len(streams)),
        "streams_without_samples": float(empty),
        "rate_min_hz": float(min(rates, default=0.0)),
        "rate_mean_hz": float(np.mean(rates)) if rates else 0.0,
        "p50_ms": _percentile(lat, 50),
        "p95_ms": _percentile(lat, 95),
        "p99_ms": _percentile(lat, 99),
        "dropped_input": float(sum(s.dropped_input for s in streams) / max(len(streams), 1)),
        "dropped_client": float(sum(s.dropped_client for s in streams)),
        "server_cpu_pct": 100.0 * cpu_s / wall_s,
        "server_rss_mb": mem[0],
        "server_peak_rss_mb": mem[1],
        "generator_cpu_pct": result["generator_cpu_pct"],
    }
    print(
        f"{label:<28} streams {len(streams):3d}  rate min/mean {out['rate_min_hz']:6.1f}/{out['rate_mean_hz']:6.1f} Hz"
        f"  latency p50/p95/p99 {out['p50_ms']:6.1f}/{out['p95_ms']:6.1f}/{out['p99_ms']:6.1f} ms"
        f"  dropped input {out['dropped_input']:.0f} client {out['dropped_client']:.0f}"
        f"  server CPU {out['server_cpu_pct']:5.1f} %  RSS {mem[0]:.0f} MB (peak {mem[1]:.0f})"
        f"  load generator CPU {out['generator_cpu_pct']:5.1f} %"
    )
    if empty:
        print(f"{'':<28} {empty} of {len(streams)} streams received no sample: their latency is unknown, not 0")
    if trained := result["gp_trained"]:
        out["gp_trained_median"] = float(np.median(trained))
        print(
            f"{'':<28} GP-EKF models trained and installed per session, min/median/max "
            f"{min(trained)}/{np.median(trained):.0f}/{max(trained)} (walking {wall_s:.0f} s from a cold start)"
        )
    return out


def run_loadbench(
    sessions: int = 10,
    clients: int = 2,
    rate: float = 200.0,
    seconds: float = 20.0,
    batch_ms: float = 33.0,
    gp_ekf: bool = False,
    nodes: int = 0,
    database_url: str = "",
) -> dict[str, dict[str, float]]:
    """Start a server, measure the single-stream baseline, then the full load; print and return both.
    ``gp_ekf``: every session also runs the GP-EKF, retraining as it walks (:func:`_run`). ``nodes``: the
    server is ``serve --workers nodes`` on ``database_url`` (PostgreSQL), every client goes through its nginx,
    and the server's CPU and memory are those of the supervisor, the nodes and nginx together."""
    with tempfile.TemporaryDirectory() as d:
        env, flags = None, ["--no-demo", "--no-leg-view"]
        if nodes:
            env = {**os.environ, "GAITSCOPE_DATABASE_URL": database_url}
            flags += ["--workers", str(nodes)]
        server = start_server(d, *flags, env=env, timeout=60 + 60 * nodes)
        proc, base = server.proc, server.base
        try:
            print(
                f"server pid {proc.pid} on {base}; {os.cpu_count()} cores; batch_ms={batch_ms}; {seconds:.0f} s each"
                + ("; every session runs the GP-EKF too" if gp_ekf else "")
                + (f"; {nodes} nodes behind nginx (serve --workers {nodes})" if nodes else "; one process")
            )
            results = {}
            for label, n, m in (
                ("baseline: 1 device x 1 client", 1, 1),
                (f"load: {sessions} devices x {clients} clients", sessions, clients),
            ):
                cpu0, t0 = _proc_cpu_s(proc.pid), time.monotonic()
                result = _run(base, n, m, rate, seconds, batch_ms, gp_ekf)
                cpu, wall = _proc_cpu_s(proc.pid) - cpu0, time.monotonic() - t0
                results[label.split(":")[0]] = _summary(label, result, cpu, wall, _proc_mem_mb(proc.pid))
                if nodes:
                    with urllib.request.urlopen(f"{base}/api/sessions", timeout=10) as r:
                        ran = sorted(json.loads(r.read()), key=lambda x: x["id"])[-n:]
                    spread = Counter(str(x["node"]) for x in ran)
                    print(f"{'':<28} sessions per node: {dict(sorted(spread.items()))}")
            load, baseline = results["load"], results["baseline"]
            met = load["p95_ms"] < TARGET_P95_MS and not load["streams_without_samples"]  # NaN compares False
            print(
                f"p95 latency under load / baseline: {load['p95_ms'] / baseline['p95_ms']:.2f}x; "
                f"target p95 < {TARGET_P95_MS:.0f} ms: {'met' if met else 'NOT met'}; "
                f"frames dropped at the server: {load['dropped_input'] + load['dropped_client']:.0f}"
            )
            return results
        finally:
            server.stop()
