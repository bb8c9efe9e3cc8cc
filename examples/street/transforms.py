"""Focal length and windows of street photos under the transforms of issue 24 item 2.

    .venv/bin/python -m examples.street.transforms OUT_TMP 185,192,200 orig,gray,jpeg,mirror,crop,rot

Photos: ../shared/real/spb_facades/images/img_N.jpg (not shipped). One JSON line per photo and
transform: focal source, f, interval, detections, posed and plausible windows, planes, and why the
vanishing points were not used. The transforms are those of tests/test_real_photo_invariance.py.
"""
import json
import sys
import time
from pathlib import Path
from PIL import Image

from pipeline.photo import reconstruct_photo, PhotoOptions

SPB = Path(__file__).resolve().parents[2].parent / 'shared' / 'real' / 'spb_facades' / 'images'
TMP = Path(sys.argv[1]); TMP.mkdir(parents=True, exist_ok=True)
names = sys.argv[2].split(',')
variants = sys.argv[3].split(',') if len(sys.argv) > 3 else ['orig']

def make(name, v):
    src = SPB / f'img_{name}.jpg'
    if v == 'orig': return src
    im = Image.open(src); im.load()
    dst = TMP / f'{name}_{v}.jpg'
    if v == 'gray': im.convert('L').save(dst, quality=95)
    elif v == 'jpeg': im.save(dst, quality=80)
    elif v == 'mirror': im.transpose(Image.FLIP_LEFT_RIGHT).save(dst, quality=95)
    elif v == 'crop':
        W, H = im.size; dx, dy = round(W*0.05), round(H*0.05)
        im.crop((dx, dy, W-dx, H-dy)).save(dst, quality=95)
    elif v == 'rot':  # pixels rotated, EXIF orientation 6 puts them back
        ex = Image.Exif(); ex[0x0112] = 6
        im.transpose(Image.ROTATE_90).save(dst, quality=95, exif=ex)
    return dst

for n in names:
    for v in variants:
        t = time.time()
        d = reconstruct_photo(make(n, v), options=PhotoOptions(export=False))
        ks = d['K_source']
        ok = sum(w['failure'] is None for w in d['windows'])
        exp = sum(bool(w['plausible']) for w in d['windows'])
        print(json.dumps({'photo': n, 'variant': v, 'source': ks['source'], 'f': round(ks['focal_px'], 1),
                          'interval': [round(x) for x in ks['interval_px']], 'n_det': len(d['windows']), 'n_ok': ok, 'n_plausible': exp, 'walls': len(d['walls']),
                          'vp': ks['unavailable'].get('vanishing points', 'ok')[:80], 's': round(time.time()-t, 1)}), flush=True)
