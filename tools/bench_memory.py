"""Peak memory and wall time of `fenestra reconstruct` on huge inputs, measured with /usr/bin/time -v.

    .venv/bin/python tools/bench_memory.py [--out out/bench-memory] [--skip-max-windows] [--only CASE]

Cases (inputs generated into --out, each run through the CLI as a user would):
  ids-65535      a 6000x4000 instance map with 65535 ids (--masks): must stop with a one-line error
                 (more than LIMITS.max_windows_per_photo) in bounded memory.
  ids-max        the same photo with LIMITS.max_windows_per_photo ids: reconstructed (sparse masks),
                 export included.
  photo-6000x4000  a 6000x4000 JPEG through the default learned detector (resized input).
  photo-12000x9000 a 12000x9000 JPEG of a plaster façade with 12 framed windows through the default
                 learned detector, K withheld (the focal chain decides), export included (issue
                 #37: <= 2 GB, <= 60 s; inpainting and the texture run at a capped size);
                 photo-12000x9000-masks: the same photo with its instance map (--masks) instead.
Prints one line per case: exit code, peak RSS (GB), wall time (s); the target is <= 2 GB.
Not a test: timings depend on the machine (the fault suite, tests/faults/, checks the behaviour).
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from fenestra.conventions import LIMITS  # noqa: E402

H, W = 4000, 6000


def instance_map(n_ids: int) -> np.ndarray:
    """(H, W) uint16 map with ids 1..n_ids, each a small rectangle on a regular grid."""
    cols = int(np.ceil(np.sqrt(n_ids * W / H)))
    rows = int(np.ceil(n_ids / cols))
    ch, cw = H // rows, W // cols
    inst = np.zeros((H, W), np.uint16)
    for k in range(n_ids):
        r, c = divmod(k, cols)
        y0, x0 = r * ch + ch // 4, c * cw + cw // 4
        inst[y0:y0 + max(1, ch // 2), x0:x0 + max(1, cw // 2)] = k + 1
    return inst


def photo(inst: np.ndarray | None = None) -> np.ndarray:
    """(H, W, 3) uint8: light wall, dark voids where inst > 0 (or one dark window)."""
    img = np.full((H, W, 3), 185, np.uint8)
    if inst is None:
        img[1000:1600, 1500:1900] = 30
    else:
        img[inst > 0] = 30
    return img


def facade_12000x9000() -> tuple[np.ndarray, np.ndarray]:
    """(photo (9000, 12000, 3) uint8 BGR, instance map (9000, 12000) uint16): a rendered plaster
    wall (low-frequency shading, pixel noise, a cornice band above each storey) with 3 storeys x 4
    windows, each a light frame around a dark glass pane with a cross bar; ids 1..12 cover each
    window's frame outline. (A brick wall's thousands of mortar segments would measure the
    vanishing-point line fit instead: see docs/performance.md.)"""
    h, w = 9000, 12000
    rng = np.random.default_rng(37)
    shade = cv2.resize(rng.normal(0.0, 10.0, size=(9, 12)).astype(np.float32), (w, h), interpolation=cv2.INTER_CUBIC)
    base = np.array([150, 185, 205], np.float32)  # BGR: ochre plaster
    img = np.empty((h, w, 3), np.uint8)
    for y0 in range(0, h, 1000):  # in bands: no full-size float copy
        y1 = min(h, y0 + 1000)
        noise = rng.normal(0.0, 4.0, size=(y1 - y0, w, 1)).astype(np.float32)
        img[y0:y1] = np.clip(base + shade[y0:y1, :, None] + noise, 0, 255).astype(np.uint8)
    for yc in (900, 3800, 6700):
        img[yc:yc + 120] = (170, 205, 225)  # cornice
        img[yc + 120:yc + 150] = (110, 135, 150)  # its shadow
    inst = np.zeros((h, w), np.uint16)
    k = 0
    for y0 in (1200, 4100, 7000):
        for x0 in (1400, 4200, 7000, 9800):
            k += 1
            y1, x1 = y0 + 1500, x0 + 900
            img[y0:y1, x0:x1] = (235, 235, 235)  # frame
            img[y0 + 80:y1 - 80, x0 + 80:x1 - 80] = (60, 45, 40)  # glass
            img[(y0 + y1) // 2 - 30:(y0 + y1) // 2 + 30, x0:x1] = (235, 235, 235)  # transom
            img[y0:y1, (x0 + x1) // 2 - 30:(x0 + x1) // 2 + 30] = (235, 235, 235)  # mullion
            inst[y0:y1, x0:x1] = k
    return img, inst


def measure(args: list[str], cwd: Path) -> tuple[int, float, float, str]:
    """(exit code, peak RSS GB, wall s, last stderr line) of one CLI run under /usr/bin/time -v."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYOPENGL_PLATFORM": "egl", "MPLBACKEND": "Agg"}
    r = subprocess.run(["/usr/bin/time", "-v", sys.executable, "-m", "fenestra", *args], cwd=cwd, env=env,
                       capture_output=True, text=True)
    rss_kb = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", r.stderr).group(1))
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): ([\d:.]+)", r.stderr).group(1)
    secs = sum(float(x) * 60 ** i for i, x in enumerate(reversed(wall.split(":"))))
    own = [ln for ln in r.stderr.splitlines() if ln.startswith(("error:", "warning:"))]
    return r.returncode, rss_kb / 2**20, secs, own[-1] if own else ""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out/bench-memory"))
    ap.add_argument("--skip-max-windows", action="store_true", help="skip the (slow) ids-max case")
    ap.add_argument("--only", choices=["photo-12000x9000", "photo-12000x9000-masks"], help="run only this case")
    a = ap.parse_args()
    d = a.out.resolve()
    d.mkdir(parents=True, exist_ok=True)
    if a.only:
        img, inst = facade_12000x9000()
        cv2.imwrite(str(d / "huge.jpg"), img, [cv2.IMWRITE_JPEG_QUALITY, 90])
        cv2.imwrite(str(d / "huge-masks.png"), inst)
        del img, inst
        masks = ["--masks", "huge-masks.png"] if a.only.endswith("-masks") else []
        rc, gb, secs, msg = measure(["reconstruct", "huge.jpg", *masks, "--out", "r-huge", "--force"], d)
        print(f"{a.only} exit {rc}, peak {gb:.2f} GB, {secs:.1f} s  {msg[:110]}", flush=True)
        return
    cv2.imwrite(str(d / "big.jpg"), photo())
    cv2.imwrite(str(d / "ids65535.png"), instance_map(65535))
    cases = [("ids-65535", ["reconstruct", "big.jpg", "--fx", "5000", "--masks", "ids65535.png",
                            "--out", "r-ids65535", "--force"])]
    if not a.skip_max_windows:
        inst = instance_map(LIMITS.max_windows_per_photo)
        cv2.imwrite(str(d / "idsmax.png"), inst)
        cv2.imwrite(str(d / "idsmax.jpg"), photo(inst))
        cases.append(("ids-max", ["reconstruct", "idsmax.jpg", "--fx", "5000", "--masks", "idsmax.png",
                                  "--snapper", "none", "--out", "r-idsmax", "--force"]))
    cases.append(("photo-6000x4000", ["reconstruct", "big.jpg", "--fx", "5000", "--snapper", "none",
                                      "--out", "r-big", "--force"]))
    print(f"{'case':<16} {'exit':>4} {'peak GB':>8} {'wall s':>7}  message")
    for name, args in cases:
        rc, gb, secs, msg = measure(args, d)
        print(f"{name:<16} {rc:>4} {gb:>8.2f} {secs:>7.1f}  {msg[:110]}", flush=True)


if __name__ == "__main__":
    main()
