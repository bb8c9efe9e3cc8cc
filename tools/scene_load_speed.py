"""Scene load times: `python tools/scene_load_speed.py [NAME ...]` prints first and cached load per house.

The first load goes into a fresh temporary cache (ifcopenshell geometry + ground truth); the
cached load is the median of three loads from that cache.
"""
from __future__ import annotations

import argparse
import statistics
import tempfile
import time

from fenestra.scenes import list_scenes, load_scene


def time_load(name: str, cache_dir: str, repeats: int = 3) -> tuple[float, float, int]:
    """(first load s, median cached load s, number of windows) for one house."""
    t0 = time.perf_counter()
    scene = load_scene(name, cache_dir=cache_dir)
    first = time.perf_counter() - t0
    cached = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        load_scene(name, cache_dir=cache_dir)
        cached.append(time.perf_counter() - t0)
    return first, statistics.median(cached), len(scene.windows)


def main(names: list[str]) -> None:
    print(f"{'house':<14} {'windows':>7} {'first s':>8} {'cached s':>9}")
    with tempfile.TemporaryDirectory() as cache:
        for name in names or list_scenes():
            first, cached, n = time_load(name, cache)
            print(f"{name:<14} {n:>7} {first:>8.2f} {cached:>9.3f}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description="first and cached scene load time per bundled house")
    ap.add_argument("names", nargs="*", help="houses (default: every bundled one)")
    main(ap.parse_args().names)
