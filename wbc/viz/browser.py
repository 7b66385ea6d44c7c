"""Headless Chromium on a viewer's page: screenshots for tests, the README and the report.

Drives Debian's ``chromium`` (or any Chromium/Chrome on the ``PATH``) through playwright's
Python package, with the system browser (``executable_path``) — nothing is downloaded. WebGL
renders in software (SwiftShader), so this works on a machine without a GPU or display.

::

    with Browser() as browser:
        page = browser.open(viewer.url)          # waits until the scene is drawn
        browser.screenshot(page, "robot.png")

Needs ``playwright`` (in the ``[viz]`` extra) and a Chromium binary (:func:`find_chromium`).
"""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import numpy as np

from wbc.errors import WbcError

__all__ = ["Browser", "BrowserUnavailableError", "browser_unavailable_reason", "find_chromium",
           "image_of", "robot_pixels"]

#: Chromium flags: no sandbox (containers, root), WebGL in software
CHROMIUM_ARGS = ("--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                 "--ignore-gpu-blocklist")
CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


class BrowserUnavailableError(WbcError):
    """No Chromium binary or no playwright package."""


def find_chromium() -> str | None:
    """The path of a Chromium binary: ``$WBC_CHROMIUM``, else the first of
    :data:`CANDIDATES` on the ``PATH``, else ``None``."""
    explicit = os.environ.get("WBC_CHROMIUM")
    if explicit:
        return explicit if os.path.isfile(explicit) else None
    for name in CANDIDATES:
        found = shutil.which(name)
        if found:
            return found
    return None


def browser_unavailable_reason() -> str | None:
    """Why screenshots cannot be taken here (``None`` when they can)."""
    if find_chromium() is None:
        return ("no Chromium found (apt-get install chromium, or set WBC_CHROMIUM to a "
                "Chromium binary)")
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return 'the playwright package is not installed (pip install ".[viz]")'
    return None


class Browser:
    """A headless Chromium (see the module docstring); a context manager."""

    def __init__(self, width: int = 960, height: int = 640) -> None:
        reason = browser_unavailable_reason()
        if reason:
            raise BrowserUnavailableError(reason)
        from playwright.sync_api import sync_playwright

        self.size = {"width": int(width), "height": int(height)}
        self._playwright = sync_playwright().start()
        try:
            self._browser = self._playwright.chromium.launch(
                executable_path=find_chromium(), headless=True, args=list(CHROMIUM_ARGS))
        except Exception:
            self._playwright.stop()
            raise

    def open(self, url: str, timeout_s: float = 30.0):
        """A new page at ``url``, returned once the 3-D scene has drawn something (the canvas
        is not one uniform colour)."""
        page = self._browser.new_page(viewport=self.size)  # type: ignore[arg-type]
        page.goto(url, timeout=timeout_s * 1e3)
        page.wait_for_selector("canvas", timeout=timeout_s * 1e3)
        # the client's "software WebGL" notice would cover a corner of every picture
        page.add_style_tag(content=".mantine-Notification-root, .mantine-Notifications-root"
                                   " { display: none !important; }")
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            image = image_of(page)
            if image.reshape(-1, image.shape[-1]).std(axis=0).max() > 3:
                page.wait_for_timeout(500)  # the meshes arrive in several messages
                return page
            page.wait_for_timeout(200)
        raise WbcError(f"the page {url} drew no scene within {timeout_s} s")

    @staticmethod
    def hide_panel(page) -> None:
        """Hide the page's control panel (for pictures of the scene alone): the positioned
        box around the "Connected" header."""
        page.evaluate("""() => {
            for (const el of document.querySelectorAll('div')) {
                if (el.children.length > 0 || (el.innerText || '').trim() !== 'Connected')
                    continue;
                let box = el;
                while (box.parentElement && !['fixed', 'absolute'].includes(
                        getComputedStyle(box).position))
                    box = box.parentElement;
                box.style.display = 'none';
            }
        }""")

    @staticmethod
    def screenshot(page, path: str | os.PathLike[str]) -> np.ndarray:
        """Save the page as a PNG at ``path``; returns the image (H, W, 3) uint8."""
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(path))
        return _read_png(Path(path).read_bytes())

    def close(self) -> None:
        try:
            self._browser.close()
        finally:
            self._playwright.stop()

    def __enter__(self) -> Browser:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def image_of(page) -> np.ndarray:
    """The page as an RGB image (H, W, 3) uint8."""
    return _read_png(page.screenshot())


def _read_png(data: bytes) -> np.ndarray:
    import io

    import matplotlib.image

    image = matplotlib.image.imread(io.BytesIO(data), format="png")
    if image.dtype != np.uint8:
        image = (np.clip(image, 0, 1) * 255).round().astype(np.uint8)
    return image[..., :3]


def robot_pixels(image: np.ndarray, background: np.ndarray | None = None,
                 threshold: int = 40) -> np.ndarray:
    """A mask of the pixels that differ from ``background`` (an image of the same page
    without the robot, or by default the image's most common colour) by more than
    ``threshold`` in some channel."""
    image = np.asarray(image, int)
    if background is None:
        flat = image.reshape(-1, 3)
        colours, counts = np.unique(flat, axis=0, return_counts=True)
        background = colours[np.argmax(counts)]
    return (np.abs(image - np.asarray(background, int)) > threshold).any(axis=-1)
