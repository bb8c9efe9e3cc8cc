"""report.html in a real headless browser (Chromium from Debian's packages, `make sysdeps`): it
loads, its lead figure is shown in the first screen, and no image is broken.

The browser is driven over the Chrome DevTools Protocol on a pipe (``--remote-debugging-pipe``:
JSON messages, NUL-terminated, the browser reads fd 3 and writes fd 4), so no Python package is
needed. The report is built from a small synthetic run with a synthetic real-photo counterpart
(bench.synthetic), so the photo column is drawn too.
"""
from __future__ import annotations

import base64
import fcntl
import json
import os
import select
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from synthetic_results import synthetic_results
from fenestra.reports.build import build_report
from test_reports_build import _write_run  # the same tiny-run writer as the report tests

BROWSERS = ("chromium", "chromium-browser")
VIEWPORT = {"width": 1280, "height": 1000}
TIMEOUT_S = 60.0

PAGE_STATE = """(async () => {
  const imgs = [...document.images];
  await Promise.all(imgs.map(i => i.decode().catch(() => null)));
  const lead = document.getElementById("lead_ranked");
  const box = lead ? lead.getBoundingClientRect() : null;
  const refs = [...document.querySelectorAll("[src],[href]")].map(e => e.getAttribute("src") || e.getAttribute("href"));
  return {readyState: document.readyState, h1: (document.querySelector("h1") || {}).textContent,
          images: imgs.map(i => ({id: i.id, complete: i.complete, width: i.naturalWidth, height: i.naturalHeight})),
          lead: lead && {width: lead.naturalWidth, top: box.top, shownWidth: box.width, shownHeight: box.height,
                         first: imgs[0] === lead, foldedAway: !!lead.closest("details")},
          details: document.querySelectorAll("details").length,
          openDetails: document.querySelectorAll("details[open]").length,
          external: refs.filter(u => !u.startsWith("data:") && !u.startsWith("#")),
          viewportHeight: innerHeight};
})()"""


def find_browser() -> str:
    """Path of the Chromium binary; fails (not skips) naming `make sysdeps` when there is none."""
    for name in BROWSERS:
        path = shutil.which(name)
        if path:
            return path
    pytest.fail(f"no headless browser ({' or '.join(BROWSERS)}) on PATH: run `make sysdeps` "
                "(installs Debian's chromium package), then rerun the tests")


def _high_fd(fd: int) -> int:
    """A duplicate of fd numbered >= 10, so the child's dup2 onto 3 and 4 cannot clobber it."""
    hi = fcntl.fcntl(fd, fcntl.F_DUPFD, 10)
    os.close(fd)
    return hi


class Browser:
    """Headless Chromium with one page, driven over the DevTools protocol on a pipe."""

    def __init__(self, binary: str, profile_dir: Path):
        to_browser_r, self._to_browser = (_high_fd(fd) for fd in os.pipe())
        self._from_browser, from_browser_w = (_high_fd(fd) for fd in os.pipe())

        def child_fds():  # runs in the child before exec: the protocol pipe on fds 3 and 4
            os.dup2(to_browser_r, 3)
            os.dup2(from_browser_w, 4)

        self.proc = subprocess.Popen(
            [binary, "--headless", "--no-sandbox", "--disable-gpu", "--remote-debugging-pipe",
             "--no-first-run", "--no-default-browser-check", f"--user-data-dir={profile_dir}", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            close_fds=False, preexec_fn=child_fds)
        os.close(to_browser_r)
        os.close(from_browser_w)
        self._buf, self._next_id, self.events = b"", 0, []
        target = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        self.session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        self.call("Page.enable", session=True)
        self.call("Emulation.setDeviceMetricsOverride",
                  {**VIEWPORT, "deviceScaleFactor": 1, "mobile": False}, session=True)

    def _read_message(self, deadline: float) -> dict:
        while b"\0" not in self._buf:
            ready, _, _ = select.select([self._from_browser], [], [], max(0.0, deadline - time.monotonic()))
            if not ready:
                raise TimeoutError(f"Chromium sent nothing for {TIMEOUT_S:.0f} s")
            chunk = os.read(self._from_browser, 1 << 20)
            if not chunk:
                raise RuntimeError(f"Chromium closed the protocol pipe (exit code {self.proc.poll()})")
            self._buf += chunk
        msg, self._buf = self._buf.split(b"\0", 1)
        return json.loads(msg)

    def call(self, method: str, params: dict | None = None, session: bool = False) -> dict:
        """Send one command; its result (RuntimeError naming the method on a protocol error)."""
        self._next_id += 1
        msg = {"id": self._next_id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = self.session
        os.write(self._to_browser, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + TIMEOUT_S
        while True:
            reply = self._read_message(deadline)
            if reply.get("id") == self._next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply["result"]
            self.events.append(reply)

    def wait_event(self, name: str) -> dict:
        deadline = time.monotonic() + TIMEOUT_S
        while True:
            for i, e in enumerate(self.events):
                if e.get("method") == name:
                    return self.events.pop(i)
            self.events.append(self._read_message(deadline))

    def open(self, url: str) -> dict:
        """Load url, wait for its load event, return PAGE_STATE evaluated in the page."""
        self.events.clear()
        self.call("Page.navigate", {"url": url}, session=True)
        self.wait_event("Page.loadEventFired")
        r = self.call("Runtime.evaluate", {"expression": PAGE_STATE, "awaitPromise": True,
                                           "returnByValue": True}, session=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"page script failed: {r['exceptionDetails']}")
        return r["result"]["value"]

    def screenshot(self, path: Path) -> Path:
        path.write_bytes(base64.b64decode(self.call("Page.captureScreenshot", {"format": "png"}, session=True)["data"]))
        return path

    def close(self) -> None:
        try:
            self.call("Browser.close")
        except (RuntimeError, TimeoutError, OSError):
            pass
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self._to_browser)
        os.close(self._from_browser)


@pytest.fixture(scope="module")
def report_html(tmp_path_factory):
    root = tmp_path_factory.mktemp("browser")
    sim = _write_run(root / "sim", synthetic_results(n_windows=60, seed=4), "synthetic")
    real_df = synthetic_results(n_windows=30, seed=9, snap_factor={"good": (1.4, 0.5), "bad": (0.7, 0.0)})
    real = _write_run(root / "real", real_df, "real-synthetic", kind="real")
    html, _ = build_report(sim, real_dir=real)
    return html


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    b = Browser(find_browser(), tmp_path_factory.mktemp("chromium-profile"))
    yield b
    b.close()


def test_report_loads_with_its_lead_figure_in_the_first_screen(report_html, browser, tmp_path):
    state = browser.open(report_html.as_uri())
    assert state["readyState"] == "complete" and state["h1"].startswith("Fenestra benchmark report")
    lead = state["lead"]
    assert lead is not None, "no <img id=lead_ranked> in report.html"
    assert lead["first"] and not lead["foldedAway"]
    assert lead["width"] > 0 and lead["shownHeight"] > 200  # decoded, and drawn at a readable size
    assert 0 <= lead["top"] < state["viewportHeight"] - 200  # the first screen shows (most of) it
    assert state["details"] >= 5 and state["openDetails"] == 0  # the details are folded
    assert state["external"] == []  # one self-contained file
    shot = browser.screenshot(tmp_path / "report.png")
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_report_has_no_broken_image(report_html, browser):
    state = browser.open(report_html.as_uri())
    assert len(state["images"]) == 6  # lead + 2 figure-8 + recall + conditions + aspect/rotation
    broken = [i["id"] for i in state["images"] if not (i["complete"] and i["width"] > 0 and i["height"] > 0)]
    assert broken == []


def test_the_browser_check_sees_a_broken_image(browser, tmp_path):
    """The same check on a page whose second image is not a PNG: it must report that image."""
    import cv2
    import numpy as np

    ok, png = cv2.imencode(".png", np.zeros((2, 3, 3), np.uint8))  # 3 px wide, 2 high
    assert ok
    page = tmp_path / "broken.html"
    page.write_text(f'<!DOCTYPE html><html><body><h1>t</h1><img id="ok" src="data:image/png;base64,'
                    f'{base64.b64encode(png.tobytes()).decode()}"><img id="bad" src="data:image/png;base64,'
                    f'{base64.b64encode(b"not a png").decode()}"></body></html>')
    state = browser.open(page.as_uri())
    assert {i["id"]: (i["width"], i["height"]) for i in state["images"]} == {"ok": (3, 2), "bad": (0, 0)}
