"""The Glass Curtain Wall Installation Dataset (B. Johns et al. 2023, CC BY 4.0; bundled in
data/real/curtainwall) -> LabelledViews (:func:`read_curtainwall`): pane masks, the known pane
size and the dataset's calibration."""
from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from fenestra.bench.real.adapters.common import components, dataset_file_or_none, dataset_photos
from fenestra.bench.views import LabelledView, LabelledWindow
from fenestra.images import decode_file, read_image
from fenestra.pipeline.io import Camera, check_distortion, read_camera, undistort_photo
from fenestra.userfiles import inside, read_json

# Calibration for 1536 x 2048 px photos (the dataset's user guide; OpenCV, pixel centres at
# integers) and the glass pane size.
CURTAIN_SIZE_PX = (1536, 2048)
CURTAIN_K = ((1821.04993399032, 0.0, 740.82871031754), (0.0, 1817.92066001349, 1018.94855509992),
             (0.0, 0.0, 1.0))
CURTAIN_DISTORTION = (-0.1552775701035, 0.0472686081157939, 0.0, 0.0, 0.0)
CURTAIN_PANE_M = (0.0932, 0.1432)  # glass pane width, height (m, 1:25 model)
CURTAIN_MIN_AREA_FRAC = 20000 / (1536 * 2048)  # smaller glass components are not panes


def curtain_glass(rgba: np.ndarray) -> np.ndarray:
    """(H, W) bool glass label of a curtain-wall mask (BGRA as cv2 reads it: pure blue, alpha >= 128)."""
    if rgba is None or rgba.ndim != 3 or rgba.shape[2] != 4:
        raise ValueError(f"curtain-wall mask must be RGBA, got shape {None if rgba is None else rgba.shape}")
    b, g, r, a = (rgba[..., i] for i in range(4))
    return (b == 255) & (g == 0) & (r == 0) & (a >= 128)


def curtain_camera(folder: Path, width: int, height: int) -> Camera:
    """``folder/K.json`` (K + distortion) if present, else the dataset's calibration scaled to
    width x height (pixel centres at integers: f' = s f, c' = (c + 0.5) s - 0.5)."""
    k = dataset_file_or_none(folder, "K.json", "intrinsics file")
    if k is not None:
        read_json(k, "intrinsics file")  # size limit (before parsing)
        return read_camera(k)
    s = width / CURTAIN_SIZE_PX[0]
    if abs(height / CURTAIN_SIZE_PX[1] - s) > 1e-3:
        raise ValueError(f"{folder}: photo {width}x{height} is not a scaled 1536x2048 curtain-wall photo; add K.json")
    K = np.array(CURTAIN_K, dtype=np.float64)
    K[:2, :2] *= s
    K[:2, 2] = (K[:2, 2] + 0.5) * s - 0.5
    return Camera(K=K, distortion=check_distortion(list(CURTAIN_DISTORTION)))


def read_curtainwall(path: Path, min_area_frac: float = CURTAIN_MIN_AREA_FRAC,
                     dataset: str = "curtainwall", refused: list[str] | None = None) -> Iterator[LabelledView]:
    """Glass Curtain Wall Installation Dataset layout: ``images/imgNNN.(png|jpg)`` as taken (lens
    distortion in them), ``masks/maskNNN.png`` (RGBA, in the undistorted frame: glass = blue),
    optional ``K.json`` (each inside ``path`` once resolved, a regular file). The photo is undistorted; panes are the 4-connected glass components
    covering at least ``min_area_frac`` of the photo; whole panes have aspect 93.2/143.2 and size
    (0.0932, 0.1432) m, panes cut by the border are partial (aspect unknown). All coplanar."""
    folder = Path(path)
    for p in dataset_photos(inside(folder, "images", "curtain-wall images folder"), refused):
        mname = str(Path("masks") / (p.stem.replace("img", "mask") + ".png"))
        mpath = dataset_file_or_none(folder, mname, "curtain-wall mask")
        if mpath is None:
            raise FileNotFoundError(f"curtain-wall mask not found: {folder / mname}")
        photo = read_image(p)
        h, w = photo.shape[:2]
        rgba = decode_file(mpath, cv2.IMREAD_UNCHANGED, "curtain-wall mask")
        if rgba.shape[:2] != (h, w):
            raise ValueError(f"{mpath}: mask {rgba.shape[1]}x{rgba.shape[0]} != photo {w}x{h}")
        cam = curtain_camera(folder, w, h)
        wins = []
        for i, c in enumerate(components(curtain_glass(rgba), min_area_frac * w * h, str(mpath))):
            cut = c.touches_border
            wins.append(LabelledWindow(id=f"{p.stem}:{i}", mask=c.sparse(), partial=cut,
                                       aspect=None if cut else CURTAIN_PANE_M[0] / CURTAIN_PANE_M[1],
                                       size_m=None if cut else CURTAIN_PANE_M))
        yield LabelledView(dataset=dataset, name=p.stem, image=undistort_photo(photo, cam), windows=tuple(wins),
                           K=cam.K, distortion_removed=None if cam.distortion is None else tuple(cam.distortion.tolist()),
                           coplanar=True)
