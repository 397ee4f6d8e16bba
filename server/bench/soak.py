"""``gaitscope loadbench --soak``: a bounded soak of a real server with faults injected.

Starts ``gaitscope serve`` (no demo, no leg view) on a data folder that is, where the machine allows
it (root and ``mount -t tmpfs``), a small file system sized to fill up about two thirds into the
run, so that the disk guard has to finish the recordings and stop the sessions cleanly. N devices
stream cohort walking at their declared rate and, every ``fault_every_s``, each sends one bad frame
(NaN time, an implausible velocity, a binary message, broken JSON, a clock jump); device 0 reboots
halfway (disconnects and comes back with its clock at 0); one more device floods the server for a
fifth of the run. At the end every session still running is stopped, and the run reports, per
device: frames sent, torque replies, torques out of bounds (must be 0), frames recorded (counted in
the MCAP files themselves, not taken from the database) and lost (answered but not recorded), and
how each session ended.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import os
import shutil
import subprocess
import tempfile
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gaitscope.server.bench.disk_rate import measure
from gaitscope.server.bench.launch import start_server
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.formats.mcap_io import read_messages
from gaitscope.sessions.synth.trials import replay_input, sensor_trial

#: Session time (s) of the recording measured for the disk budget (server/bench/disk_rate.py).
_RATE_MEASURED_S = 5.0
MAX_TORQUE = 30.0
#: One bad frame of each kind, in turn (``None``: a binary message).
_BAD_FRAMES: tuple[str | bytes, ...] = (
    '{"type": "frame", "seq": 0, "t": NaN, "foot_angle_deg": 1.0}',
    "FOOT_VEL",  # a plausible frame with foot_vel_dps = 1e50 (filled in at send time)
    b"\x00\x01binary",
    '{"type": "frame", "seq": ',
    "JUMP",  # a plausible frame 1e10 s ahead
)


@dataclass
class DeviceReport:
    """What one device client saw."""

    session_id: int
    sent: int = 0
    bad_sent: int = 0
    torques: int = 0
    out_of_bounds: int = 0
    notices: int = 0
    reconnects: int = 0
    closed: str = ""
    recorded: int = 0
    ended: str = ""
    trials: list[str] = field(default_factory=list)
    notice_kinds: dict[str, int] = field(default_factory=dict)
    bytes: int = 0

    @property
    def lost(self) -> int:
        """Frames answered with a torque but missing from the recordings."""
        return max(0, self.torques - self.recorded)


@contextlib.contextmanager
def _small_disk(size_mb: int) -> Iterator[tuple[Path, bool]]:
    """A temporary folder on a ``size_mb`` tmpfs when mounting is allowed; else a plain one."""
    with tempfile.TemporaryDirectory(prefix="gaitscope-soak-") as d:
        folder = Path(d)
        mounted = False
        if os.geteuid() == 0 and shutil.which("mount"):
            mount = ["mount", "-t", "tmpfs", "-o", f"size={size_mb}m", "tmpfs", str(folder)]
            r = subprocess.run(mount, capture_output=True, check=False)
            mounted = r.returncode == 0
        try:
            yield folder, mounted
        finally:
            if mounted:
                subprocess.run(["umount", "-l", str(folder)], capture_output=True, check=False)


def _api(base: str, method: str, path: str, body: dict[str, object] | None = None) -> tuple[int, Any]:
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(base + path, data=data, headers={"Content-Type": "application/json"}, method=method)
    try:
        with urllib.request.urlopen(req, timeout=20) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read() or b"null")


def _walk_frames(rate: float) -> list[dict[str, object]]:
    sensors, _, _ = sensor_trial([(1.2, 0.0, 40)], rate_hz=rate)
    data = replay_input(sensors)
    return [{"type": "frame", **{k: float(v[i]) for k, v in data.signals.items()}} for i in range(len(data.time_s))]


async def _device(
    ws_base: str,
    token: str,
    report: DeviceReport,
    frames: list[dict[str, object]],
    rate: float,
    seconds: float,
    fault_every_s: float,
    reboot_at_s: float | None,
) -> None:
    """Stream at ``rate`` with a bad frame every ``fault_every_s``; reboot once at ``reboot_at_s``."""
    import websockets

    loop = asyncio.get_running_loop()
    start = loop.time()
    k, clock0, next_fault, bad_k = 0, 0.0, fault_every_s, 0
    rebooted = reboot_at_s is None
    while loop.time() - start < seconds and not report.closed:
        try:
            url = f"{ws_base}/ws/devices/{report.session_id}?token={token}"
            async with websockets.connect(url, max_queue=None) as ws:

                async def replies(ws: websockets.ClientConnection = ws) -> None:
                    async for text in ws:
                        msg = json.loads(text)
                        if msg["type"] == "torque":
                            report.torques += 1
                            tau = msg["torque_Nm"]
                            if not (isinstance(tau, float) and math.isfinite(tau) and 0.0 <= tau <= MAX_TORQUE):
                                report.out_of_bounds += 1
                        else:
                            report.notices += 1
                            kind = str(msg.get("kind"))
                            report.notice_kinds[kind] = report.notice_kinds.get(kind, 0) + 1

                reader = asyncio.create_task(replies())
                while (elapsed := loop.time() - start) < seconds:
                    if not rebooted and reboot_at_s is not None and elapsed >= reboot_at_s:
                        rebooted, clock0 = True, k / rate  # the device's clock restarts at 0
                        report.reconnects += 1
                        break
                    due = start + k / rate
                    if due > loop.time():
                        await asyncio.sleep(due - loop.time())
                    t = k / rate - clock0  # the device's own sample clock
                    frame = dict(frames[k % len(frames)])
                    frame.update(seq=k, t=t, sent_ns=time.time_ns())
                    if elapsed >= next_fault:
                        next_fault += fault_every_s
                        bad = _BAD_FRAMES[bad_k % len(_BAD_FRAMES)]
                        bad_k += 1
                        report.bad_sent += 1
                        if bad == "FOOT_VEL":
                            await ws.send(json.dumps({**frame, "foot_vel_dps": 1e50}))
                        elif bad == "JUMP":
                            await ws.send(json.dumps({**frame, "t": t + 1e10}))
                        else:
                            await ws.send(bad)
                    else:
                        await ws.send(json.dumps(frame))
                        report.sent += 1
                    k += 1
                await asyncio.sleep(0.3)
                reader.cancel()
                with contextlib.suppress(asyncio.CancelledError, Exception):
                    await reader
        except websockets.ConnectionClosed as e:
            report.closed = f"closed by the server: {e.rcvd.code if e.rcvd else '?'} {e.rcvd.reason if e.rcvd else ''}"
        except (OSError, websockets.InvalidStatus) as e:
            report.closed = f"refused: {e}"


async def _flood(ws_base: str, session_id: int, token: str, start_s: float, seconds: float) -> dict[str, Any]:
    """Send as fast as the socket takes frames for ``seconds``, after ``start_s``. The server may end the
    session before or during the flood (the disk guard): the refusal or the close is reported, not raised."""
    import websockets

    counts: dict[str, Any] = {"sent": 0, "torques": 0, "notices": 0, "closed": ""}
    await asyncio.sleep(start_s + 2.0)  # the other process's clients take about 2 s to start
    try:
        async with websockets.connect(f"{ws_base}/ws/devices/{session_id}?token={token}", max_queue=None) as ws:

            async def replies() -> None:
                async for text in ws:
                    counts["torques" if json.loads(text)["type"] == "torque" else "notices"] += 1

            reader = asyncio.create_task(replies())
            loop = asyncio.get_running_loop()
            stop = loop.time() + seconds
            k = 0
            try:
                while loop.time() < stop:
                    for _ in range(100):
                        await ws.send(json.dumps({"type": "frame", "seq": k, "t": k * 5e-5, "foot_angle_deg": 10.0}))
                        k += 1
                    counts["sent"] = k
                    await asyncio.sleep(0)
                await asyncio.sleep(0.3)
            finally:
                reader.cancel()
                with contextlib.suppress(asyncio.CancelledError, Exception):
                    await reader
    except websockets.ConnectionClosed as e:
        counts["closed"] = f"closed by the server: {e.rcvd.code if e.rcvd else '?'} {e.rcvd.reason if e.rcvd else ''}"
    except (OSError, websockets.InvalidStatus) as e:
        counts["closed"] = f"refused: {e}"
    return counts


def _worker(
    ws_base: str, ids: list[int], tokens: dict[int, str], rate: float, seconds: float, fault_every_s: float
) -> list[DeviceReport]:
    """The steady devices, in a process of their own (uvloop), so the generator is not the bottleneck."""
    import uvloop

    frames = _walk_frames(rate)
    reports = [DeviceReport(i) for i in ids]

    async def main() -> None:
        await asyncio.gather(
            *(
                _device(
                    ws_base,
                    tokens[r.session_id],
                    r,
                    frames,
                    rate,
                    seconds,
                    fault_every_s,
                    seconds / 2 if n == 0 else None,
                )
                for n, r in enumerate(reports)
            )
        )

    uvloop.run(main())
    return reports


def _flood_worker(ws_base: str, flood_id: int, token: str, seconds: float) -> dict[str, Any]:
    """The flooding device, in another process, so that it does not slow the steady ones' clients."""
    import uvloop

    return uvloop.run(_flood(ws_base, flood_id, token, 0.3 * seconds, 0.2 * seconds))


def run_soak(devices: int = 4, rate: float = 200.0, seconds: float = 60.0, fault_every_s: float = 2.0) -> dict:
    """Run the soak, print the report, and return it."""
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    # What the devices' recordings take: measured, for the channels they send and the stack that runs for them
    # (they do not declare their channels); the flooding one records at most 1.25 x rate for a fifth of the run.
    walking = [k for k in _walk_frames(rate)[0] if k != "type"]
    per_device = measure(walking, rate, _RATE_MEASURED_S, declared=False).bytes_per_s
    expected_mb = (devices + 1.25 * 0.2) * per_device * seconds / 2**20
    stop_mb = 8
    size_mb = int(stop_mb + 0.6 * expected_mb) + 1  # the guard stops about two thirds in
    with _small_disk(size_mb) as (folder, mounted):
        env = dict(os.environ)
        if mounted:
            env.update(GAITSCOPE_DISK_WARN_MB=str(stop_mb + 8), GAITSCOPE_DISK_STOP_MB=str(stop_mb))
        server = start_server(folder, "--no-demo", "--no-leg-view", env=env, timeout=60)
        base = server.base
        print(
            f"soak: {devices} devices at {rate:g} Hz + 1 flooding device, {seconds:g} s, a bad frame every "
            f"{fault_every_s:g} s per device, device 0 reboots at {seconds / 2:g} s; each records "
            f"{per_device / 1000:.0f} kB/s (measured); data folder "
            + (f"on a {size_mb} MiB tmpfs (disk stop at {stop_mb} MiB free)" if mounted else "on the normal disk "
               "(no small file system could be mounted here: the full-disk fault is not injected)")
        )  # fmt: skip
        try:
            _, subject = _api(base, "POST", "/api/subjects", {"code": "SOAK1", "leg_length_m": 0.9, "mass_kg": 75})
            sid = subject["id"]
            source = {"kind": "device", "rate_hz": rate}
            body = {"subject_id": sid, "source": source, "settings": {"max_torque_Nm": MAX_TORQUE}}
            ids = [_api(base, "POST", "/api/sessions", body)[1]["id"] for _ in range(devices + 1)]
            tokens = {i: _api(base, "POST", f"/api/sessions/{i}/device-tokens")[1]["token"] for i in ids}
            ws_base = base.replace("http://", "ws://")
            with ProcessPoolExecutor(max_workers=2, mp_context=get_context("spawn")) as pool:
                steady = pool.submit(_worker, ws_base, ids[:-1], tokens, rate, seconds, fault_every_s)
                flooding = pool.submit(_flood_worker, ws_base, ids[-1], tokens[ids[-1]], seconds)
                reports, flood = steady.result(), flooding.result()
            for i in ids:
                _api(base, "POST", f"/api/sessions/{i}/stop")
            for r in reports:
                _, session = _api(base, "GET", f"/api/sessions/{r.session_id}")
                _, events = _api(base, "GET", f"/api/sessions/{r.session_id}/events")
                _, trials = _api(base, "GET", f"/api/trials?session_id={r.session_id}")
                endings = [e["text"] for e in events if e["text"].startswith(("session stopped", "session failed"))]
                r.ended = session["state"] + (f" ({endings[-1]})" if endings else " (by the API)")
                r.trials = [t["status"] for t in trials]
                r.bytes = sum((folder / t["path"]).stat().st_size for t in trials)
                r.recorded = sum(_recorded(folder / t["path"]) for t in trials)
        finally:
            server.stop()
    _print(reports, flood)
    clean = all(r.ended.startswith(("stopped", "failed")) and all(s == "finished" for s in r.trials) for r in reports)
    return {"devices": reports, "flood": flood, "clean": clean, "disk_fault": mounted}


def _recorded(path: Path) -> int:
    """Gait states in a trial's file (0 for a file that cannot be read: its trial says ``damaged``)."""
    try:
        return sum(1 for _ in read_messages(path, ["/gait_state"]))
    except (OSError, DataFormatError):
        return 0


def _print(reports: list[DeviceReport], flood: dict[str, Any]) -> None:
    head = ("device", "sent", "bad", "torques", "notices", "out of bounds", "recorded", "lost")
    print(" ".join(f"{h:>{w}}" for h, w in zip(head, (6, 7, 4, 8, 7, 13, 9, 5), strict=True)) + "  ended")
    for n, r in enumerate(reports):
        print(
            f"{n:>6} {r.sent:>7} {r.bad_sent:>4} {r.torques:>8} {r.notices:>7} {r.out_of_bounds:>13} {r.recorded:>9} "
            f"{r.lost:>5}  "
            f"{r.ended}; trials {', '.join(r.trials)}; notices {r.notice_kinds}"
            + (f"; device {r.closed}" if r.closed else "")
        )
    keys = ("sent", "torques", "out_of_bounds", "recorded", "lost", "bytes")
    total = {k: sum(getattr(r, k) for r in reports) for k in keys}
    print(
        f"total: {total['sent']} good frames sent, {total['torques']} torque replies, {total['out_of_bounds']} out of "
        f"bounds, {total['recorded']} recorded, {total['lost']} lost; flooding device sent {flood['sent']}, got "
        f"{flood['torques']} torques and {flood['notices']} notices"
        + (f" ({flood['closed']})" if flood["closed"] else "")
        + f"; {total['bytes'] / max(total['recorded'], 1):.0f} recorded bytes per sample"
    )
