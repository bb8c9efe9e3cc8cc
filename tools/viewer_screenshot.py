"""The README's picture of the reconstruct folder's page (index.html, pipeline.export.viewer).

    .venv/bin/python tools/viewer_screenshot.py [--png docs/img/viewer.png] [--keep DIR]

Runs the README's quick start, ``fenestra reconstruct`` on the bundled curtain-wall photo
(examples/curtainwall/img017.jpg with its K.json and pane masks, CC BY 4.0: Glass Curtain Wall
Installation Dataset, B. Johns, E. Abdi, M. Arashpour, 2023, doi:10.26180/23538198), into a
temporary folder (``--keep DIR``: into DIR, kept), opens its index.html from file:// in headless
Chromium (tests/headless_browser.py, `make sysdeps`), waits until the embedded model.glb has
loaded, and writes a screenshot of the page: the overlay, the model in 3D and the window table.
Only this bundled photo is used: the St Petersburg street photos must not be copied into the
repository. Exit 1 when the model did not load (no picture written).
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))  # the headless browser (tests/headless_browser.py)

from headless_browser import Browser, browser_path  # noqa: E402

EX = "examples/curtainwall/"  # run from the checkout's root: the page quotes these paths
COMMAND = ["reconstruct", EX + "img017.jpg", "--K", EX + "K.json", "--masks", EX + "panes017.png", "--width", "0.0932"]
# (the README's quick start)
VIEWPORT = {"width": 1280, "height": 800}
WIDTH_PX = 960  # the picture's width (the page is shot at VIEWPORT and scaled down)
LOADED = """new Promise(resolve => {
  const t0 = Date.now();
  const tick = () => {
    const s = document.body.dataset.model;
    if (s === "loading" && Date.now() - t0 < 40000) { setTimeout(tick, 50); return; }
    requestAnimationFrame(() => resolve({model: s, meshes: document.body.dataset.meshes, title: document.title}));
  };
  tick();
})"""


def screenshot(page: Path, png: Path, profile: Path) -> dict:
    """Open ``page`` in headless Chromium and write its first screen to ``png`` (scaled to WIDTH_PX
    wide); the page's model state."""
    import cv2  # noqa: PLC0415

    binary = browser_path()
    if binary is None:
        raise SystemExit("no headless browser (chromium) on PATH: run `make sysdeps`")
    b = Browser(binary, profile, LOADED, viewport=VIEWPORT)
    try:
        state = b.open(page.as_uri())
        if state["model"] != "loaded":
            return state
        shot = profile / "shot.png"
        b.screenshot(shot)
    finally:
        b.close()
    img = cv2.imread(str(shot))
    h = round(img.shape[0] * WIDTH_PX / img.shape[1])
    img = cv2.resize(img, (WIDTH_PX, h), interpolation=cv2.INTER_AREA)
    png.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(png), img, [cv2.IMWRITE_PNG_COMPRESSION, 9]):
        raise SystemExit(f"cannot write {png}")
    return state


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--png", type=Path, default=ROOT / "docs" / "img" / "viewer.png", help="the picture to write")
    ap.add_argument("--keep", type=Path, default=None, help="write the reconstruct folder here and keep it")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="fenestra-viewer-") as tmp:
        out = args.keep or Path(tmp) / "curtainwall"
        cmd = [sys.executable, "-m", "fenestra", *COMMAND, "--out", str(out)]
        print("$ fenestra " + " ".join(cmd[3:]), flush=True)
        subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
        profile = Path(tmp) / "chromium-profile"
        profile.mkdir()
        state = screenshot(out / "index.html", args.png, profile)
    if state["model"] != "loaded":
        print(f"the page's model did not load ({state}); no picture written", file=sys.stderr)
        return 1
    print(f"{state['title']}: wrote {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
