"""Pages of the e2e suite: a browser page that records what it logged, and readings of its plots.

Every e2e test checks that its page logged no console error and that no request left 127.0.0.1:
:func:`watch` opens a page that records both in a :class:`Watched`. The fixtures that hand these out
(``server``, ``browser``, ``watched``) are in ``conftest.py``.
"""

from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final
from urllib.parse import urlsplit

import numpy as np
from playwright import sync_api as playwright_api

from gaitscope.server.bench.launch import LOOPBACK
from tests.e2e.accounts import log_in

CHROMIUM: Final = Path("/usr/bin/chromium")
#: Screenshots of the views, for a person to look at (not compared).
ARTIFACTS: Final = Path(__file__).resolve().parent / "artifacts"
LAUNCH_ARGS: Final = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-dev-shm-usage",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


def leaves_loopback(url: str) -> bool:
    """True if a request to ``url`` would go to a host other than 127.0.0.1 (blob:/data: stay local)."""
    if url.startswith("data:"):
        return False
    if url.startswith("blob:"):
        url = url[len("blob:") :]
    parts = urlsplit(url)
    return parts.scheme in {"http", "https", "ws", "wss"} and parts.hostname != LOOPBACK


_FAILED_LOAD = re.compile(r"Failed to load resource: the server responded with a status of (\d{3})")


@dataclass
class Watched:
    """A page plus what it logged. Chromium logs every 4xx response as a console error; the refusals a
    test provokes on purpose are declared with :meth:`allow_refusal`, and only those are let through."""

    page: playwright_api.Page
    console_errors: list[str] = field(default_factory=list)
    external: list[str] = field(default_factory=list)
    requests: int = 0
    allowed: list[tuple[int, re.Pattern[str]]] = field(default_factory=list)

    def allow_refusal(self, status: int, url_pattern: str) -> None:
        self.allowed.append((status, re.compile(url_pattern)))

    def on_console(self, msg: playwright_api.ConsoleMessage) -> None:
        if msg.type != "error":
            return
        m = _FAILED_LOAD.search(msg.text)
        url = str(msg.location.get("url", ""))
        if m and any(int(m[1]) == st and pat.search(url) for st, pat in self.allowed):
            return
        self.console_errors.append(f"{msg.text} ({url})")

    def check_clean(self) -> None:
        assert self.console_errors == [], "console errors:\n" + "\n".join(self.console_errors)
        assert self.external == [], f"requests left {LOOPBACK}: {self.external}"


def base_of(server: object) -> str:
    """A module's ``server`` fixture's base URL (a string, or an object with ``base``)."""
    return server if isinstance(server, str) else str(server.base)


def watch(
    browser: playwright_api.Browser,
    base: str | None,
    user: str | None = "clinician",
    viewport: tuple[int, int] = (1024, 768),
    timeout_ms: float = 15_000,
) -> tuple[playwright_api.BrowserContext, Watched]:
    """A new context and page recording console errors and foreign requests, logged in as ``user`` (through
    the API, before any page loads; None: not logged in). Close the context when done."""
    context = browser.new_context(viewport={"width": viewport[0], "height": viewport[1]})
    if user is not None and base is not None:
        log_in(context, base, user)
    page = context.new_page()
    page.set_default_timeout(timeout_ms)
    w = Watched(page)

    def on_request(req: playwright_api.Request) -> None:
        w.requests += 1
        if leaves_loopback(req.url):
            w.external.append(req.url)

    page.on("console", w.on_console)
    page.on("pageerror", lambda e: w.console_errors.append(f"uncaught: {e}"))
    page.on("request", on_request)
    page.on("websocket", lambda ws: w.external.append(ws.url) if leaves_loopback(ws.url) else None)
    return context, w


def wait_responsive(page: playwright_api.Page, timeout_s: float = 30.0) -> None:
    """Wait until the renderer draws frames promptly again (three two-frame round trips under 100 ms)."""
    deadline = time.monotonic() + timeout_s
    fast = 0
    while fast < 3:
        ms = page.evaluate(
            "() => new Promise((r) => { const t0 = performance.now();"
            " requestAnimationFrame(() => requestAnimationFrame(() => r(performance.now() - t0))); })"
        )
        fast = fast + 1 if ms < 100 else 0
        assert time.monotonic() < deadline, f"the page stayed busy for {timeout_s} s (last frame pair {ms:.0f} ms)"


def _legend_number(text: str) -> float | None:
    """A legend value as a float; None for uPlot's missing value (and anything that is not a number)."""
    try:
        v = float(text)
    except ValueError:
        return None
    return v if math.isfinite(v) else None


def sweep(page: playwright_api.Page, plot: playwright_api.Locator, xs: np.ndarray) -> list[dict[str, float | None]]:
    """The plot's legend (label -> value, the x axis first) with the mouse at each fraction ``xs`` of its width."""
    plot.scroll_into_view_if_needed()
    out = []
    for x in xs:
        box = plot.locator(".u-over").bounding_box()
        assert box is not None, "the plot has no drawing area"
        page.mouse.move(box["x"] + x * box["width"], box["y"] + box["height"] / 2)
        page.wait_for_timeout(30)
        rows = plot.evaluate(
            "el => [...el.querySelectorAll('.u-legend .u-series')]"
            ".map((r) => [r.querySelector('.u-label').textContent, r.querySelector('.u-value').textContent])"
        )
        out.append({label: _legend_number(value) for label, value in rows})
    return out
