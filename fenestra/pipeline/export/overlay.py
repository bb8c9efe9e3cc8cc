"""Overlay PNG: the pipeline's quads and the reprojected 3D window drawn on the photo, with a
side panel (legend, header lines, each window's status and reason) to its right, no taller than the
photo: with many windows its font shrinks, then its entries flow into more columns (panel_layout).

Colours (RGB, like the image): mask-fit quad yellow, snapped quad magenta, reprojected 3D window
green (void outline at the facade and the frame's back outline, depth edges between), window axes
x red, y green, z blue (length half the window height). Flagged (not exported) windows: orange
quad; failed windows: red quad, or their detection box where no quad was found. A partial window
(cut by the photo's border: its visible part, ``WindowResult.partial``) has its visible quad drawn
dashed, cyan when exported (orange or red like any flagged or failed window), and its panel line
names the edges that cut it. Each window's number is drawn once where it is; its reason is in the
panel.
"""
from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from fenestra.checks import check_image, check_K
from fenestra.conventions import project
from fenestra.pipeline.export.geometry import place
from fenestra.pipeline.messages import edges_words, failure_message
from fenestra.pipeline.types import Unavailable, WindowResult

COLOURS = {"mask": (255, 220, 0), "snapped": (255, 0, 255), "reprojected": (0, 230, 0),
           "x": (255, 0, 0), "y": (0, 200, 0), "z": (0, 80, 255), "failed": (255, 40, 40),
           "flagged": (255, 150, 0), "exported": (0, 230, 0), "partial": (0, 220, 255)}
_SHIFT = 4  # fractional bits for sub-pixel drawing


def _pts(px: np.ndarray) -> np.ndarray:
    return np.round(np.asarray(px, dtype=np.float64) * (1 << _SHIFT)).astype(np.int32)


def _segment(img, a, b, colour, thick):
    if np.all(np.isfinite(a)) and np.all(np.isfinite(b)):
        cv2.line(img, tuple(_pts(a)), tuple(_pts(b)), colour, thick, cv2.LINE_AA, _SHIFT)


def _poly(img, quad, colour, thick):
    cv2.polylines(img, [_pts(quad)], True, colour, thick, cv2.LINE_AA, _SHIFT)


def _dashed(img, quad, colour, thick, dash_px: float):
    """A closed quad (4, 2) px drawn dashed: dashes and gaps of ``dash_px`` along each side."""
    q = np.asarray(quad, dtype=np.float64).reshape(-1, 2)
    for a, b in zip(q, np.roll(q, -1, axis=0)):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / (2.0 * dash_px))))
        for k in range(n):
            s0, s1 = 2 * k / (2 * n), (2 * k + 1) / (2 * n)
            _segment(img, a + s0 * (b - a), a + s1 * (b - a), colour, thick)


def _text(img, s, at, colour, scale):
    """Text drawn once, on a dark box (readable on any photo; no second stroke of other glyph widths),
    moved inside the image where it would leave it (a label of a window at the top or right edge)."""
    thick = max(1, int(round(scale * 1.5)))
    (w, h), base = cv2.getTextSize(s, cv2.FONT_HERSHEY_SIMPLEX, scale, thick)
    H, W = img.shape[:2]
    x = min(max(float(at[0]), 2.0), max(W - w - 3.0, 2.0))
    y = min(max(float(at[1]), h + 3.0), max(H - base - 1.0, h + 3.0))
    at = (int(round(x)), int(round(y)))
    x0, y0 = max(at[0] - 2, 0), max(at[1] - h - 3, 0)
    cv2.rectangle(img, (x0, y0), (at[0] + w + 2, at[1] + base), (20, 20, 20), cv2.FILLED)
    cv2.putText(img, s, at, cv2.FONT_HERSHEY_SIMPLEX, scale, colour, thick, cv2.LINE_AA)


def _draw_3d(img, K, result, thick, depth_m: float = 0.07):
    """Reprojected window box (facade outline, back outline, depth edges) and axes."""
    pw = place(result)
    if isinstance(pw, Unavailable):  # no usable pose: nothing to reproject
        return
    front = pw.void_corners()
    back = front - [0.0, 0.0, depth_m]
    P = np.concatenate([front, back])
    ok = pw.to_camera(P)[:, 2] > 1e-6
    px = project(K, pw.R, pw.t, P)
    for i in range(4):
        j = (i + 1) % 4
        for a, b in ((i, j), (4 + i, 4 + j), (i, 4 + i)):
            if ok[a] and ok[b]:
                _segment(img, px[a], px[b], COLOURS["reprojected"], thick)
    L = 0.5 * pw.height_m
    axes = np.array([[0, 0, 0], [L, 0, 0], [0, L, 0], [0, 0, L]], dtype=np.float64)
    ok = pw.to_camera(axes)[:, 2] > 1e-6
    apx = project(K, pw.R, pw.t, axes)
    for k, name in enumerate("xyz", start=1):
        if ok[0] and ok[k]:
            _segment(img, apx[0], apx[k], COLOURS[name], thick + 1)


def _status(r: WindowResult, exclude: dict[int, str]) -> tuple[str, str]:
    """("exported" | "flagged" | "failed", one line) for the panel and the colour."""
    if r.failure:
        return "failed", failure_message(r.failure, () if r.partial is None else r.partial.cut)
    if r.index in exclude:
        return "flagged", exclude[r.index]
    placed = place(r)
    if isinstance(placed, Unavailable):
        return "failed", placed.reason
    if r.partial is not None:
        seen = "" if r.partial.visible_fraction is None else f", {100 * r.partial.visible_fraction:.0f} % seen"
        return "exported", (f"partial (cut by {edges_words(r.partial.cut)}{seen}): "
                            f"{placed.width_m:.2f} x {placed.height_m:.2f} m")
    return "exported", f"{placed.width_m:.2f} x {placed.height_m:.2f} m, w/h {r.aspect_ratio:.3f}"


def _wrap(s: str, width: int) -> list[str]:
    words, lines, line = s.split(), [], ""
    for w in words:
        if line and len(line) + 1 + len(w) > width:
            lines.append(line)
            line = w
        else:
            line = f"{line} {w}" if line else w
    return lines + ([line] if line else [])


MIN_PANEL_SCALE = 0.3  # the smallest panel font (cv2 Hershey scale) before the entries go into columns
LEGEND = (("mask", "mask-fit quad"), ("snapped", "snapped quad"), ("reprojected", "exported window (3D)"),
          ("flagged", "flagged: not exported"), ("failed", "failed"),
          ("partial", "partial (cut by the photo's edge): dashed"))


def _metrics(width: int, scale: float) -> tuple[int, int, int]:
    """(line step, glyph height, characters per line) px of panel text at ``scale`` in a column ``width`` px wide."""
    thick = max(1, int(round(scale * 1.5)))
    sample = "window failed: quad 0.61 x 1.52 m, w/h"  # typical text: its mean glyph width
    (sw, ch), base = cv2.getTextSize(sample, cv2.FONT_HERSHEY_SIMPLEX, scale, thick)
    return ch + base + max(2, int(round(8 * scale / 0.5))), ch, max(20, int((width - 16) * len(sample) / sw))


def _entries(results: list[WindowResult], exclude: dict[int, str], chars: int) -> list[list[tuple[str, tuple]]]:
    """Each window's panel lines (status, then its wrapped reason), one list per window."""
    out = []
    for r in results:
        kind, why = _status(r, exclude)
        out.append([(part if j == 0 else "   " + part, COLOURS[kind] if j == 0 else (200, 200, 200))
                    for j, part in enumerate(_wrap(f"#{r.index} {kind}: {why}", chars - 3))])
    return out


def panel_layout(height: int, width: int, results: list[WindowResult], exclude: dict[int, str], header: list[str],
                 scale: float) -> tuple[float, int, list[list[tuple[int, int, str, tuple]]]]:
    """Where the panel's text goes: (scale, columns, per column [(x, y, text, colour)]), y the
    baseline. Everything fits in ``height`` px: the font shrinks (to MIN_PANEL_SCALE at most), then
    the windows' entries flow into further columns of ``width`` px (an entry is never split); only a
    photo too short for the legend and header gets a taller panel."""
    s = scale
    while True:
        step, _, chars = _metrics(width, s)
        head = [(part, (235, 235, 235)) for line in header for part in _wrap(line, chars)] + [("", (235, 235, 235))]
        entries = _entries(results, exclude, chars)
        rows = max(1, (height - step // 2) // step)
        top = len(LEGEND) + 1 + len(head)
        if top + sum(map(len, entries)) <= rows or s <= MIN_PANEL_SCALE:
            break
        s = max(MIN_PANEL_SCALE, s * 0.85)
    rows = max(rows, top + (max(map(len, entries)) if entries else 0))  # too short a photo: a taller panel
    columns, y = [[]], step * (top + 1)
    for k, (text, colour) in enumerate(head):
        if text:
            columns[0].append((8, step * (len(LEGEND) + 2 + k), text, colour))
    for entry in entries:
        if y // step + len(entry) - 1 > rows:
            columns.append([])
            y = step
        for text, colour in entry:
            columns[-1].append((8 + width * (len(columns) - 1), y, text, colour))
            y += step
    return s, len(columns), columns


def _panel(height: int, width: int, results: list[WindowResult], exclude: dict[int, str], header: list[str],
           scale: float) -> tuple[tuple[int, int], Callable[[np.ndarray], None]]:
    """The side panel: its size (rows, columns) px, at least ``height`` rows of width x columns, and
    a function that draws it (legend, header lines, one entry per window, laid out by
    :func:`panel_layout` so that it is no taller than ``height``) into an (rows, columns, 3) uint8
    RGB array filled with the background grey (the overlay's canvas: no panel-sized copy)."""
    s, n_cols, columns = panel_layout(height, width, results, exclude, header, scale)
    step, ch, _ = _metrics(width, s)
    bottom = max([y for col in columns for _, y, _, _ in col] + [step * (len(LEGEND) + 1)])
    return (max(height, bottom + step), width * n_cols), lambda panel: _draw_panel(panel, columns, step, ch, s)


def _draw_panel(panel: np.ndarray, columns: list, step: int, ch: int, s: float) -> None:
    """Draw the legend and the laid-out text ``columns`` (:func:`panel_layout`) into ``panel`` in place."""
    y = step
    for name, label in LEGEND:
        cv2.rectangle(panel, (8, y - ch), (8 + ch, y), COLOURS[name], cv2.FILLED)
        _text(panel, label, (16 + ch, y), (235, 235, 235), s)
        y += step
    for col in columns:
        for x, y, text, colour in col:
            _text(panel, text, (x, y), colour, s)


def _draw_quads(img, r: WindowResult, kind: str, boxes: dict[int, tuple], thick: int) -> None:
    """A whole window's quads: mask fit (yellow), snapped (magenta, or its status colour), or its
    detection box (a failed window without a quad)."""
    if r.quad_mask is not None:
        _poly(img, r.quad_mask, COLOURS["mask"], thick)
    if r.quad_snapped is not None:
        _poly(img, np.asarray(r.quad_snapped, dtype=np.float64), COLOURS["snapped"] if kind == "exported"
              else COLOURS[kind], thick + (kind != "exported"))
    elif r.quad_mask is None and r.index in boxes:
        x0, y0, x1, y1 = boxes[r.index]
        _poly(img, np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64), COLOURS["failed"], thick)


def draw_overlay(image: np.ndarray, K: np.ndarray, results: list[WindowResult], exclude: dict[int, str] | None = None,
                 boxes: dict[int, tuple] | None = None, header: list[str] | None = None) -> np.ndarray:
    """(H', W + panel, 3) uint8 RGB (H' >= H: taller when the panel needs it; the photo stays at the
    top left, pixel for pixel): a copy of the RGB ``image`` with every result drawn where it is
    (its quads, its reprojected 3D window, its number), and a side panel on the right with the
    legend, ``header`` lines (e.g. the intrinsics' source) and each window's status and reason.

    exclude: {index: reason} of windows not exported (drawn in the "flagged" colour); boxes:
    {index: (x0, y0, x1, y1) px} of detections, drawn for failed windows without a quad.
    """
    image = check_image(image)
    K = check_K(K)
    exclude, boxes = exclude or {}, boxes or {}
    H, W = image.shape[:2]
    thick = max(1, int(round(min(H, W) / 400)))
    scale = max(0.4, min(H, W) / 1600)
    (rows, cols), draw_panel = _panel(H, max(360, int(0.4 * W)), results, exclude, header or [], scale)  # >= H rows
    # one canvas, the photo copied in once and everything drawn on it in place (a 100 Mpx photo: no second copy)
    canvas = np.full((rows, W + cols, 3), 30, np.uint8)  # a long list: a dark band below
    draw_panel(canvas[:, W:])
    img = canvas[:H, :W]
    img[...] = image
    for r in results:
        kind, _ = _status(r, exclude)
        dashed = r.partial is not None and r.quad_snapped is not None  # its visible quad (the mask fit, not snapped)
        if not dashed:
            _draw_quads(img, r, kind, boxes, thick)
        if kind == "exported":
            _draw_3d(img, K, r, thick)
        if dashed:  # over its reprojected 3D window, which runs along it
            colour = COLOURS["partial" if kind == "exported" else kind]
            _dashed(img, r.quad_snapped, colour, thick + 1, 6.0 * thick + 4.0)
        anchor = next((np.asarray(q, dtype=np.float64).min(axis=0) for q in (r.quad_snapped, r.quad_mask)
                       if q is not None), np.asarray(boxes.get(r.index, (10.0, 30.0 + 20 * r.index))[:2], dtype=np.float64))
        _text(img, f"#{r.index}", anchor + [2, -4], COLOURS[kind], scale)
    return canvas
