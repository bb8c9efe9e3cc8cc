"""Peak memory and wall time of `fenestra reconstruct` on huge inputs, measured with /usr/bin/time -v.

    .venv/bin/python tools/bench_memory.py [--out out/bench-memory] [--skip-max-windows]

Cases (inputs generated into --out, each run through the CLI as a user would):
  ids-65535      a 6000x4000 instance map with 65535 ids (--masks): must stop with a one-line error
                 (more than LIMITS.max_windows_per_photo) in bounded memory.
  ids-max        the same photo with LIMITS.max_windows_per_photo ids: reconstructed (sparse masks),
                 export included.
  photo-6000x4000  a 6000x4000 JPEG through the default learned detector (resized input).
Prints one line per case: exit code, peak RSS (GB), wall time (s); the target is <= 2 GB.
Not a test: timings depend on the machine (tests/test_faults.py checks the behaviour).
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
    a = ap.parse_args()
    d = a.out.resolve()
    d.mkdir(parents=True, exist_ok=True)
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
