"""Headless Chromium for the browser tests (the bench's report.html, the reconstruct folder's
index.html): Chromium from Debian's packages (`make sysdeps`), driven over the Chrome DevTools
Protocol on a pipe (``--remote-debugging-pipe``: JSON messages, NUL-terminated, the browser reads
fd 3 and writes fd 4), so no Python package is needed.

    b = Browser(find_browser(), profile_dir, page_state=JS)   # JS: an expression, the page's state
    state = b.open(Path("page.html").as_uri())                # load, wait for onload, evaluate JS
    b.evaluate("document.title")
    b.screenshot(Path("shot.png")); b.close()

WebGL: Chromium runs here without a GPU (``--disable-gpu``); ``--enable-unsafe-swiftshader``
gives its WebGL the software renderer (SwiftShader), which newer Chromium no longer falls back to
by itself. The pages tested are local files Fenestra wrote, so the flag's warning (untrusted web
content on a software GL) does not apply.
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

BROWSERS = ("chromium", "chromium-browser")
VIEWPORT = {"width": 1280, "height": 1000}
TIMEOUT_S = 60.0
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--use-angle=swiftshader",
         "--remote-debugging-pipe", "--no-first-run", "--no-default-browser-check")


def browser_path() -> str | None:
    """Path of the Chromium binary on PATH, or None."""
    return next((p for p in map(shutil.which, BROWSERS) if p), None)


def find_browser() -> str:
    """Path of the Chromium binary; fails (not skips) naming `make sysdeps` when there is none."""
    import pytest  # noqa: PLC0415  (the tools use this module too)

    path = browser_path()
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
    """Headless Chromium with one page, driven over the DevTools protocol on a pipe. ``page_state``:
    the JavaScript expression :meth:`open` evaluates (awaited) once the page has loaded."""

    def __init__(self, binary: str, profile_dir: Path, page_state: str = "document.readyState",
                 viewport: dict | None = None):
        self.page_state = page_state
        to_browser_r, self._to_browser = (_high_fd(fd) for fd in os.pipe())
        self._from_browser, from_browser_w = (_high_fd(fd) for fd in os.pipe())

        def child_fds():  # runs in the child before exec: the protocol pipe on fds 3 and 4
            os.dup2(to_browser_r, 3)
            os.dup2(from_browser_w, 4)

        self.proc = subprocess.Popen(
            [binary, *FLAGS, f"--user-data-dir={profile_dir}", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            close_fds=False, preexec_fn=child_fds)
        os.close(to_browser_r)
        os.close(from_browser_w)
        self._buf, self._next_id, self.events = b"", 0, []
        target = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        self.session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        self.call("Page.enable", session=True)
        self.call("Emulation.setDeviceMetricsOverride",
                  {**(viewport or VIEWPORT), "deviceScaleFactor": 1, "mobile": False}, session=True)

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

    def evaluate(self, expression: str):
        """The value of a JavaScript expression in the page (promises awaited); RuntimeError with
        the page's exception when it throws."""
        r = self.call("Runtime.evaluate", {"expression": expression, "awaitPromise": True,
                                           "returnByValue": True}, session=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"page script failed: {r['exceptionDetails']}")
        return r["result"].get("value")

    def open(self, url: str, page_state: str | None = None):
        """Load url, wait for its load event, return ``page_state`` (default: the one given to the
        constructor) evaluated in the page."""
        self.events.clear()
        self.call("Page.navigate", {"url": url}, session=True)
        self.wait_event("Page.loadEventFired")
        return self.evaluate(page_state or self.page_state)

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
