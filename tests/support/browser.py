"""Debian's Chromium, headless, driven by Playwright (never `playwright install`: no browser is
downloaded), and the processes the RCML browser's tests run: a robot's server and `browse`."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from support.processes import Running, running

CHROMIUM = Path("/usr/bin/chromium")
#: No sandbox (CI runs as root), nothing fetched or updated behind the test's back.
ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


@contextmanager
def chromium() -> Iterator[Any]:
    """A browser for a module's tests (one per module: starting one takes a second)."""
    if not CHROMIUM.exists():
        pytest.skip("Debian's chromium is not installed (.ci/run installs it)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        try:
            yield launched
        finally:
            launched.close()


@contextmanager
def serving(directory: Path, rcml: Path, *args: str) -> Iterator[Running]:
    """`rcmlconf serve RCML` on free ports, its ready file in `directory`."""
    directory.mkdir(parents=True, exist_ok=True)
    with running(directory, "serve", "--port", "0", "--http-port", "0", *args, str(rcml)) as up:
        yield up


@contextmanager
def browsing(directory: Path, panel: str, server: Running, *args: str) -> Iterator[Running]:
    """`rcmlconf browse PANEL`, its one session connected to `server` (a `serving`)."""
    directory.mkdir(parents=True, exist_ok=True)
    href = Path(panel).stem + ".rcml"
    connect = f"{href}={server.ready['rctp']}"
    with running(directory, "browse", panel, "--connect", connect, *args) as up:
        yield up
