"""The e2e suite's fixtures: ``gaitscope serve`` as a subprocess, Debian's chromium, a watched page.

Every test under ``tests/e2e`` is marked ``e2e`` (``-m "not e2e"`` leaves them out) and skipped where
Debian's chromium is not installed. A module that needs another server (restarted, or with other
settings) defines its own ``server`` fixture, which overrides this one; ``watched`` takes its base URL
from either a URL or an object with ``base``.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from playwright import sync_api as playwright_api

from tests.e2e.accounts import add_users
from tests.e2e.pages import CHROMIUM, LAUNCH_ARGS, Watched, base_of, watch
from tests.e2e.servers import start

_HERE = Path(__file__).resolve().parent
_NO_CHROMIUM = pytest.mark.skipif(
    not CHROMIUM.exists(), reason=f"Chromium not found at {CHROMIUM} (apt-get install chromium)"
)


@pytest.hookimpl(tryfirst=True)  # before `-m` selects: the marks must be there when it looks
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if item.path.is_relative_to(_HERE):
            item.add_marker(pytest.mark.e2e)
            item.add_marker(_NO_CHROMIUM)


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """``gaitscope serve`` on free ports with a fresh data folder, accounts on and one user per role; yields
    its base URL."""
    data = tmp_path_factory.mktemp("gaitscope-data")
    add_users(data)
    running = start(data)
    try:
        yield running.base
    finally:
        running.stop()


@pytest.fixture(scope="module")
def browser() -> Iterator[playwright_api.Browser]:
    with playwright_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=str(CHROMIUM), args=LAUNCH_ARGS)
        yield b
        b.close()


@pytest.fixture
def watched(browser: playwright_api.Browser, server: object) -> Iterator[Watched]:
    """A 1024x768 page (the smallest tablet we support), logged in as the clinician, recording console errors
    and foreign requests."""
    context, w = watch(browser, base_of(server))
    yield w
    context.close()
