"""Check the EfficientNet-Lite backbone's input normalisation on real photos (issue #13).

The ImageNet classifier the backbone was trained as should be most confident (highest mean top-1
probability, lowest entropy) on natural photos under the normalisation it was trained with. This
prints both statistics for (RGB - 127) / 128 (TensorFlow EfficientNet-Lite, used by
fenestra/pipeline/detectors/effwin.py), ImageNet mean/std and [0, 1], over centre crops of the photos.

    python tools/check_backbone.py [--photos '../shared/real/spb_facades/train/images/*.jpg'] [-n 24]
"""
from __future__ import annotations

import argparse
import glob
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

NORMS = {"(x-127)/128 (TF Lite, used)": ((127.0,) * 3, (128.0,) * 3),
         "ImageNet mean/std": ((123.675, 116.28, 103.53), (58.395, 57.12, 57.375)),
         "x/255": ((0.0,) * 3, (255.0,) * 3)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photos", default="../shared/real/spb_facades/train/images/*.jpg")
    ap.add_argument("-n", type=int, default=24, help="photos to use (sorted by name)")
    args = ap.parse_args()
    import numpy as np
    import torch

    from fenestra.images import read_image
    from fenestra.pipeline.detectors.effwin import efficientnet_lite

    files = sorted(glob.glob(args.photos))[:args.n]
    if not files:
        sys.exit(f"no photos match {args.photos}")
    net = efficientnet_lite(pretrained=True).eval()
    crops = []
    for f in files:
        im = read_image(f)
        h, w = im.shape[:2]
        s = min(h, w)
        import cv2
        crops.append(cv2.resize(im[(h - s) // 2:(h - s) // 2 + s, (w - s) // 2:(w - s) // 2 + s], (224, 224),
                                interpolation=cv2.INTER_AREA).astype(np.float32))
    x = torch.from_numpy(np.stack(crops)).permute(0, 3, 1, 2)
    print(f"{len(files)} photos from {args.photos}")
    for name, (mu, sd) in NORMS.items():
        xn = (x - torch.tensor(mu).view(1, 3, 1, 1)) / torch.tensor(sd).view(1, 3, 1, 1)
        with torch.no_grad():
            p = torch.softmax(net(xn), 1)
        ent = float(-(p * p.clamp_min(1e-12).log()).sum(1).mean())
        print(f"{name:30s} mean top-1 {float(p.max(1).values.mean()):.3f}  mean entropy {ent:.2f} nats")


if __name__ == "__main__":
    main()
