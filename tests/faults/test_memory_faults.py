"""Bounded memory and time on huge inputs (instance maps, photos).

Part of the fault suite (tests/faults/, README of the suite: tests/faults/conftest.py):
every case runs the CLI as a user meets the fault."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from fault_helpers import (run_measured)


def test_65535_instance_ids_are_a_clear_error_in_bounded_memory(tmp_path):
    ids = np.arange(1, 256 * 256, dtype=np.uint16).tolist() + [0]
    cv2.imwrite(str(tmp_path / "m.png"), np.array(ids, np.uint16).reshape(256, 256))
    cv2.imwrite(str(tmp_path / "p.png"), np.full((256, 256, 3), 128, np.uint8))
    rc, err, gb = run_measured(["reconstruct", "p.png", "--fx", "300", "--masks", "m.png", "--out", "o"], tmp_path)
    assert rc == 2 and "instance map has 65535 window ids, more than the 1000 per photo" in err, err[-2000:]
    assert gb < 1.0 and not (tmp_path / "o").exists()


def test_many_windows_sparse_masks_large_photo():
    """1000 windows (the stated maximum) in a 4000x3000 instance map: one Detection per id with
    its bounding-box crop (not a full-size mask each: 12 GB), quads where the rectangles are.
    In process: the CLI run of this case (export included) is measured by tools/bench_memory.py."""
    from fenestra.pipeline.detectors.oracle import detections_from_instance_map
    from fenestra.pipeline.reconstruct import fit_quads

    inst = np.zeros((3000, 4000), np.uint16)
    rects = {}
    for k in range(1000):
        r, c = divmod(k, 40)
        x0, y0 = 20 + c * 98, 20 + r * 118
        inst[y0:y0 + 60, x0:x0 + 40] = 7 + 3 * k
        rects[7 + 3 * k] = (x0, y0, x0 + 39, y0 + 59)
    dets = detections_from_instance_map(inst)
    assert [d.instance_id for d in dets] == sorted(rects)
    assert sum(d.mask.nbytes for d in dets) == 1000 * 60 * 40  # crops exactly the windows' boxes
    fits = fit_quads(dets, image_shape=inst.shape)
    for d, f in list(zip(dets, fits))[::37]:
        x0, y0, x1, y1 = rects[d.instance_id]
        # the void's outline runs half a pixel outside the outer pixel centres
        want = np.array([[x0 - .5, y0 - .5], [x1 + .5, y0 - .5], [x1 + .5, y1 + .5], [x0 - .5, y1 + .5]])
        np.testing.assert_allclose(f.result.quad, want, atol=0.05)
    with pytest.raises(Exception, match="1000 window ids, more than the 999 per photo"):
        detections_from_instance_map(inst, max_windows=999)


def test_large_photo_with_the_learned_detector(tmp_path):
    """A 3000x2000 photo: the network sees it at 1024 px, the quad comes back at full resolution
    (tools/bench_memory.py measures the 6000x4000 case). The quad is the corner head's
    (``--quad-source corners``): this test is about memory and mapping back, and on this frameless
    flat void detector v6's mask grows a bump above the window that the mask fit refuses (the masks'
    mapping back is tests/pipeline/test_pipeline_detect.py's large-photo test)."""
    img = np.full((2000, 3000, 3), 180, np.uint8)
    img[500:800, 750:950] = 30  # a dark 200 x 300 px window void
    cv2.imwrite(str(tmp_path / "big.jpg"), img)
    rc, err, gb = run_measured(["reconstruct", "big.jpg", "--fx", "2500", "--out", "o", "--snapper", "none",
                                "--quad-source", "corners"],
                               tmp_path)
    assert rc == 0, err[-2000:]
    assert gb < 2.0, gb
    doc = json.loads((tmp_path / "o" / "windows.json").read_text())
    assert doc["image_size"] == [3000, 2000] and len(doc["windows"]) == 1
    want = [[749.5, 499.5], [949.5, 499.5], [949.5, 799.5], [749.5, 799.5]]
    # one network pixel is 2.9 photo pixels: the corners within a few of them
    np.testing.assert_allclose(doc["windows"][0]["quad_mask"], want, atol=12.0)
