"""Headless Chromium for looking at the replay without a display: the browser tests, the startup
benchmark and screenshots.

It is Debian's `chromium`, driven by Python playwright through `executable_path`, so
`playwright install` is never needed. WebGL renders in software (SwiftShader), as on any
machine without a GPU.
"""

from __future__ import annotations

import contextlib
import shutil
import tempfile
from collections.abc import Iterator
from typing import Any

CHROMIUM_ARGS = (
    "--no-sandbox",  # CI containers run as root
    "--disable-gpu",
    "--enable-unsafe-swiftshader",  # software WebGL, which Chromium otherwise refuses
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
)
VIEWPORT = {"width": 1280, "height": 800}
# Triangles three.js drew in its last frame: the machine is on the canvas once this reaches
# the triangle count of its visual geoms.
RENDERED_TRIANGLES = "() => window.__viserTestpoints?.rendererInfo?.render?.triangles ?? 0"


def find_chromium() -> str | None:
    """The path of Debian's chromium, or None if it is not installed."""
    return shutil.which("chromium")


@contextlib.contextmanager
def chromium_context(chromium: str, viewport: dict[str, int] = VIEWPORT) -> Iterator[Any]:
    """A playwright browser context of headless `chromium` with a throw-away profile."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright, tempfile.TemporaryDirectory() as profile:
        context = playwright.chromium.launch_persistent_context(
            profile, executable_path=chromium, headless=True, args=list(CHROMIUM_ARGS), viewport=viewport
        )
        try:
            yield context
        finally:
            context.close()
