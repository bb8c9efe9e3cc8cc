"""report.html in a real headless browser (Chromium from Debian's packages, `make sysdeps`): it
loads, its lead figure is shown in the first screen, and no image is broken.

The browser is driven over the Chrome DevTools Protocol on a pipe (tests/headless_browser.py), so
no Python package is needed. The report is built from a small synthetic run with a synthetic real-photo counterpart
(bench.synthetic), so the photo column is drawn too.
"""
from __future__ import annotations

import base64

import pytest

from headless_browser import Browser, find_browser  # shared with test_viewer_browser.py
from synthetic_results import synthetic_results
from fenestra.reports.build import build_report
from test_reports_build import _write_run  # the same tiny-run writer as the report tests

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
    b = Browser(find_browser(), tmp_path_factory.mktemp("chromium-profile"), PAGE_STATE)
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
