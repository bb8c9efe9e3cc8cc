"""Pack rendered detector data small enough to carry to the GPU machine (its copy limit is 64 MiB).

    python fenestra/training/pack_data.py OUT.tar.xz --train-step 2 out/detector-data/{train,val,heldout-pyrender,heldout-mitsuba}

Each view's image.png is stored as JPEG bytes under the same name (OpenCV decodes by content, so
fenestra/training/dataset.py reads it unchanged), instances.png and coco.json as they are;
view.json is left out (training and evaluation do not read it). Under a path containing "/train"
only every ``train-step``-th view is kept, and its coco.json then lists only the kept views (so the
packed folder can be evaluated as it is). Unpack with ``tar -xJf OUT.tar.xz`` in the repo root.
"""
from __future__ import annotations

import argparse
import io
import json
import tarfile
from pathlib import Path

import cv2


def _add(tf: tarfile.TarFile, name: str, data: bytes) -> None:
    info = tarfile.TarInfo(name)
    info.size = len(data)
    tf.addfile(info, io.BytesIO(data))


def kept_coco(coco: dict, file_names: set[str]) -> dict:
    """The COCO dict restricted to the images whose file_name is in file_names (and their annotations)."""
    images = [im for im in coco["images"] if im["file_name"] in file_names]
    ids = {im["id"] for im in images}
    return {**coco, "images": images, "annotations": [a for a in coco["annotations"] if a["image_id"] in ids]}


def pack(out: Path, roots: list[Path], train_step: int = 1, jpeg_quality: int = 88) -> int:
    """Write the tar.xz (atomically, under fenestra.outputs' rule: never over a file Fenestra did
    not write, nor into the data it packs); return the number of views packed."""
    from fenestra import outputs  # noqa: PLC0415

    packed = []
    outputs.write_file(Path(out), lambda p: packed.append(_pack(p, roots, train_step, jpeg_quality)),
                       inputs=roots, option="OUT")
    return packed[0]


def _pack(out: Path, roots: list[Path], train_step: int, jpeg_quality: int) -> int:
    """pack's body: the tar.xz written to ``out``."""
    n = 0
    with tarfile.open(out, "w:xz", preset=3) as tf:
        for root in roots:
            for ds in sorted({p.parent for p in root.glob("**/views")}):
                step = train_step if "/train" in str(ds) else 1
                views = sorted((ds / "views").iterdir())[::step]
                _add(tf, f"{ds}/coco.json", json.dumps(kept_coco(json.loads((ds / "coco.json").read_text()),
                                                                 {f"views/{v.name}/image.png" for v in views})).encode())
                for v in views:
                    ok, jpg = cv2.imencode(".jpg", cv2.imread(str(v / "image.png")),
                                           [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality])
                    _add(tf, f"{v}/image.png", jpg.tobytes())
                    _add(tf, f"{v}/instances.png", (v / "instances.png").read_bytes())
                    n += 1
    return n


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("roots", type=Path, nargs="+")
    ap.add_argument("--train-step", type=int, default=1)
    ap.add_argument("--jpeg-quality", type=int, default=88)
    a = ap.parse_args()
    n = pack(a.out, a.roots, a.train_step, a.jpeg_quality)
    print(f"{a.out}: {n} views, {a.out.stat().st_size / 2**20:.1f} MiB")
