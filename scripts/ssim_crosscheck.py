#!/usr/bin/env python3
"""Independent SSIM values for gs-losses' cross-check test (tests/ssim_skimage.rs).

For each image pair it records
  * `skimage`: scikit-image `structural_similarity(a, b, gaussian_weights=True, sigma=1.5,
    use_sample_covariance=False, data_range=1, channel_axis=-1)`. skimage filters with reflection
    and averages only over pixels >= 5 px from the border; gs-losses' `SsimRegion::Interior` is the
    comparable quantity (the window never leaves the image there, so the border rule is moot).
  * `zero_padded`: the 3DGS definition (F.conv2d(img, window, padding=5), mean over all pixels and
    channels) written with scipy.ndimage (mode='constant', cval=0) — `SsimRegion::Full`.
Images are read as 8-bit value/255 (float64). Run from the repo root:

    python3 -m venv /tmp/v && /tmp/v/bin/pip install numpy scipy scikit-image pillow
    /tmp/v/bin/python scripts/ssim_crosscheck.py > crates/gs-losses/tests/fixtures/ssim_skimage.json
"""
import json
import os

import numpy as np
import scipy
import skimage
from PIL import Image
from scipy.ndimage import correlate1d
from skimage.metrics import structural_similarity

SHARED = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "shared")
PAIRS = [
    ("data/synth-bunny/images/0008.png", "data/synth-bunny/images/0009.png"),
    ("weights/ref/img1_astronaut.png", "weights/ref/img3_astronaut_blur1.png"),
    ("weights/ref/img1_astronaut.png", "weights/ref/img2_chelsea.png"),
    ("data/dtu-scan24/images/000000.jpg", "data/dtu-scan24/images/000001.jpg"),
]


def load(rel):
    return np.asarray(Image.open(os.path.join(SHARED, rel)).convert("RGB")).astype(np.float64) / 255.0


def ssim_zero_padded(a, b):
    x = np.arange(11) - 5
    g = np.exp(-x ** 2 / (2 * 1.5 ** 2))
    g /= g.sum()
    f = lambda im: correlate1d(correlate1d(im, g, axis=0, mode="constant"), g, axis=1, mode="constant")
    mu1, mu2 = f(a), f(b)
    s11, s22, s12 = f(a * a) - mu1 ** 2, f(b * b) - mu2 ** 2, f(a * b) - mu1 * mu2
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    m = ((2 * mu1 * mu2 + c1) * (2 * s12 + c2)) / ((mu1 ** 2 + mu2 ** 2 + c1) * (s11 + s22 + c2))
    return float(m.mean())


out = {"command": "python3 scripts/ssim_crosscheck.py", "versions": {
    "scikit-image": skimage.__version__, "scipy": scipy.__version__, "numpy": np.__version__}, "pairs": []}
for pa, pb in PAIRS:
    a, b = load(pa), load(pb)
    s = structural_similarity(a, b, gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
                              data_range=1.0, channel_axis=-1)
    out["pairs"].append({"a": pa, "b": pb, "width": a.shape[1], "height": a.shape[0],
                         "skimage": float(s), "zero_padded": ssim_zero_padded(a, b)})
print(json.dumps(out, indent=1))
