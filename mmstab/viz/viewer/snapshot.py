"""A screenshot of the viewer as a browser shows it: headless Chromium driven by Playwright.

Used by ``make view-screenshot`` (the picture of docs/viewer.md) and by the browser test. The
browser is the system's Chromium (Debian package ``chromium``, found on ``PATH`` or in
``$MMSTAB_CHROMIUM``); Playwright only drives it (nothing is downloaded). WebGL runs on
the CPU (SwiftShader), so the first frame takes a few seconds on a small machine: the
page is polled until the robot's arm colour shows, within ``timeout``.
"""

from __future__ import annotations

import io
import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from mmstab.core.files import MmstabError
from mmstab.viz.viewer.scene import ARM_RGB

#: Chromium flags: headless, software WebGL, and no calls home (the network may be closed).
CHROMIUM_ARGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--enable-unsafe-swiftshader",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-quic",
)
#: Width of the GUI panel at the right edge [px], left out of the pixel counts.
PANEL_PX = 340


def find_chromium() -> str | None:
    """The Chromium executable: ``$MMSTAB_CHROMIUM``, else ``chromium`` on ``PATH``."""
    return os.environ.get("MMSTAB_CHROMIUM") or shutil.which("chromium")


class RenderCheck(NamedTuple):
    """What a screenshot shows, left of the GUI panel.

    Attributes:
        scene_share: share of pixels that are not the white background, in [0, 1].
        arm_pixels: pixels of the arm's orange (lit or shaded).
    """

    scene_share: float
    arm_pixels: int


class Snapshot(NamedTuple):
    """A screenshot and what it shows.

    Attributes:
        png: the final screenshot (PNG bytes).
        drawn: the check of the first screenshot in which the scene showed.
        final: the check of ``png`` (after ``before``, if given).
    """

    png: bytes
    drawn: RenderCheck
    final: RenderCheck


def check_render(png: bytes) -> RenderCheck:
    """Count scene and arm pixels in a PNG screenshot of the viewer."""
    from PIL import Image

    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int32)
    view = rgb[:, : max(rgb.shape[1] - PANEL_PX, 1)]
    scene = np.any(np.abs(view - 255) > 12, axis=-1)
    r, g, b = view[..., 0], view[..., 1], view[..., 2]
    ar, ag, _ = ARM_RGB
    # the arm's hue at any brightness: red ahead of green ahead of blue, in its ratio
    hue = (r > 90) & (r > g + 40) & (g > b + 40) & (np.abs(g / np.maximum(r, 1) - ag / ar) < 0.1)
    return RenderCheck(float(scene.mean()), int(np.count_nonzero(hue)))


def screenshot(
    url: str,
    path: str | Path | None = None,
    *,
    size: tuple[int, int] = (1200, 760),
    timeout: float = 30.0,
    min_arm_pixels: int = 200,
    connected: Any = None,
    before: Any = None,
) -> Snapshot:
    """Load the viewer in headless Chromium and take a screenshot once the scene shows.

    Args:
        url: the viewer's address.
        path: where to write the PNG (atomically); ``None`` to keep it in memory only.
        size: viewport (width, height) [px].
        timeout: give up after this long [s].
        min_arm_pixels: the scene counts as drawn once this many arm pixels show.
        connected: optional callable returning True once the server sees the browser.
        before: optional callable ``(page) -> None`` run before the final screenshot.

    Returns:
        The final PNG and what the first drawn and the final screenshot show.

    Raises:
        MmstabError: no Chromium, or the scene did not show within ``timeout``.
    """
    from playwright.sync_api import sync_playwright

    exe = find_chromium()
    if exe is None:
        raise MmstabError("no chromium on PATH (Debian: apt-get install chromium)")
    deadline = time.monotonic() + timeout
    with tempfile.TemporaryDirectory(prefix="mmstab-view-chromium-") as profile:
        with sync_playwright() as pw:
            browser = pw.chromium.launch_persistent_context(
                profile,
                executable_path=exe,
                args=list(CHROMIUM_ARGS),
                viewport={"width": size[0], "height": size[1]},
                timeout=timeout * 1000,
            )
            try:
                page = browser.new_page() if not browser.pages else browser.pages[0]
                page.goto(url, timeout=timeout * 1000)
                while connected is not None and not connected():
                    if time.monotonic() > deadline:
                        raise MmstabError(f"{url}: the browser did not connect in {timeout:g} s")
                    time.sleep(0.1)
                png, seen = b"", RenderCheck(0.0, 0)
                while time.monotonic() < deadline:
                    png = page.screenshot()
                    seen = check_render(png)
                    if seen.arm_pixels >= min_arm_pixels:
                        break
                    time.sleep(0.5)
                else:
                    raise MmstabError(f"{url}: the scene did not show in {timeout:g} s ({seen})")
                drawn = seen
                if before is not None:
                    before(page)
                    png = page.screenshot()
                    seen = check_render(png)
            finally:
                browser.close()
    if path is not None:
        from mmstab.core.files import _atomic

        def write(tmp: Path) -> None:
            tmp.write_bytes(png)

        _atomic(Path(path), write)
    return Snapshot(png, drawn, seen)


def hide_notifications(page: Any) -> None:
    """Close the browser's notifications (e.g. "software WebGL"), for a clean picture."""
    for button in page.locator(".mantine-Notification-closeButton").all():
        button.click()
    page.wait_for_timeout(600)


def write_screenshot(
    problem_path: str | Path,
    run_dir: str | Path | None,
    out: str | Path,
    at: float = 0.9,
    close: float | None = None,
) -> Snapshot:
    """The docs' picture: the viewer of a problem (and run) at a share of the run, as PNG.

    Args:
        problem_path: the problem YAML file.
        run_dir: a run folder of ``mmstab track`` (or ``mmstab follow``), or ``None``.
        out: the PNG to write (e.g. ``results/view/viewer.png``).
        at: where in the run, as a share of its samples in [0, 1].
        close: the camera this far [m] from the robot, looking at it; ``None``: the whole
            scene (a long route's robot is a few pixels then).
    """
    from mmstab.core.problem import load_problem
    from mmstab.runs.store import load_run
    from mmstab.viz.viewer.server import Viewer

    problem = load_problem(problem_path)
    run = load_run(run_dir, problem) if run_dir is not None else None
    viewer = Viewer(problem, run, host="127.0.0.1", port=0)
    try:
        if run is not None:
            now = viewer.show_sample(int(round(at * (run.samples - 1))))
            if close is not None:  # the camera as the scene sets it, nearer the robot
                target = now.G_T_B[:3, 3]
                viewer.server.initial_camera.look_at = tuple(target)
                view = np.array([0.35, -0.5, 0.38])
                viewer.server.initial_camera.position = tuple(
                    target + close * view / np.linalg.norm(view)
                )
        return screenshot(
            viewer.url,
            out,
            connected=lambda: bool(viewer.server.get_clients()),
            before=hide_notifications,
        )
    finally:
        viewer.stop()


def main(argv: list[str] | None = None) -> int:
    """``python -m mmstab.viz.viewer.snapshot PROBLEM RUN_DIR OUT.png [AT [CLOSE]]``.

    ``make view-screenshot`` and ``make online``; AT is the share of the run, CLOSE the
    camera's distance from the robot [m] (default: the whole scene).
    """
    import sys

    args = sys.argv[1:] if argv is None else argv
    usage = "usage: python -m mmstab.viz.viewer.snapshot PROBLEM RUN_DIR OUT.png [AT [CLOSE]]"
    try:
        at = float(args[3]) if len(args) > 3 else 0.9
        close = float(args[4]) if len(args) > 4 else None
    except ValueError:
        args = []
    if not 3 <= len(args) <= 5:
        print(usage, file=sys.stderr)
        return 2
    try:
        shot = write_screenshot(args[0], args[1], args[2], at, close)
    except MmstabError as exc:
        print(f"mmstab: error: {exc}", file=sys.stderr)
        return 2
    print(
        f"view-screenshot: {args[2]} ({100 * shot.final.scene_share:.0f} % scene pixels, "
        f"{shot.final.arm_pixels} arm pixels)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
