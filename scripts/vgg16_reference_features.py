"""Independent reference for gs-features: VGG16 conv2_2 / conv3_3 of a real image crop with
scipy.signal.correlate (float64), written as a small test fixture.

Usage (throw-away venv outside the repo):
    python3 -m venv /tmp/gsf-venv && /tmp/gsf-venv/bin/pip install numpy scipy pillow
    /tmp/gsf-venv/bin/python scripts/vgg16_reference_features.py ../shared crates/gs-features/tests/fixtures

It reads synth-bunny images/0000.png, crops CROP = (x0, y0, w, h), normalises as torchvision
ImageNet, and runs conv1_1..conv3_3 (3x3, pad 1, bias, ReLU; 2x2 max-pool stride 2) with the
weights ROUNDED TO F16 exactly as bundled (scripts/convert_vgg16_weights.py), biases f32.
Outputs (little-endian f32, row-major [H'][W'][C], the layout of gs_features::FeatureMap):
    vgg16_ref_conv2_2.f32  (28 x 20 x 128)
    vgg16_ref_conv3_3.f32  (14 x 10 x 256)
and prints how far features from the full-f32 weights are from the f16-weight reference.
"""
import os, sys, json
import numpy as np
from PIL import Image
from scipy.signal import correlate

CROP = (200, 150, 56, 40)  # x0, y0, width, height in synth-bunny/images/0000.png
NAMES = ["conv1_1", "conv1_2", "conv2_1", "conv2_2", "conv3_1", "conv3_2", "conv3_3"]


def conv(x, w, b):
    """x: (C, H, W) float64; w: (O, C, 3, 3); zero padding 1; + bias; ReLU."""
    xp = np.pad(x, ((0, 0), (1, 1), (1, 1)))
    out = np.empty((w.shape[0],) + x.shape[1:])
    for o in range(w.shape[0]):
        # 'valid' cross-correlation over (C, H+2, W+2) with (C, 3, 3) -> (1, H, W)
        out[o] = correlate(xp, w[o], mode="valid", method="direct")[0] + b[o]
    return np.maximum(out, 0.0)


def pool(x):
    c, h, w = x.shape
    x = x[:, : h // 2 * 2, : w // 2 * 2]
    return x.reshape(c, h // 2, 2, w // 2, 2).max(axis=(2, 4))


def features(img, z, f16):
    x = (img - z["input_mean"].astype(np.float64)[:, None, None]) / z["input_std"].astype(np.float64)[:, None, None]
    out = {}
    for i, n in enumerate(NAMES):
        if i in (2, 4):
            x = pool(x)
        w = z[n + "_weight"]
        w = (w.astype(np.float16) if f16 else w).astype(np.float64)
        x = conv(x, w, z[n + "_bias"].astype(np.float64))
        if n in ("conv2_2", "conv3_3"):
            out[n] = x
    return out


def main(shared, outdir):
    z = np.load(os.path.join(shared, "weights/vgg16_imagenet_conv1_1-conv3_3.npz"))
    png = np.asarray(Image.open(os.path.join(shared, "data/synth-bunny/images/0000.png")).convert("RGB"))
    x0, y0, w, h = CROP
    img = png[y0 : y0 + h, x0 : x0 + w].astype(np.float64).transpose(2, 0, 1) / 255.0
    ref = features(img, z, f16=True)
    full = features(img, z, f16=False)
    stats = {"crop": CROP}
    for n, a in ref.items():
        hwc = np.ascontiguousarray(a.transpose(1, 2, 0)).astype("<f4")
        path = os.path.join(outdir, f"vgg16_ref_{n}.f32")
        hwc.tofile(path + ".tmp")
        os.replace(path + ".tmp", path)
        d = np.abs(full[n] - a)
        stats[n] = dict(shape=list(hwc.shape), sum=float(a.sum()), mean_abs=float(np.abs(a).mean()),
                        max=float(a.max()), f32_weights_max_abs_diff=float(d.max()),
                        f32_weights_max_rel_diff=float(d.max() / a.max()),
                        f32_weights_mean_abs_diff=float(d.mean()))
    print(json.dumps(stats, indent=1))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
