"""Convert the shared VGG16 npz (conv1_1..conv3_3, OIHW f32) into gs-features' bundled blob.

Usage (throw-away venv with numpy, outside the repo):
    python3 -m venv /tmp/gsf-venv && /tmp/gsf-venv/bin/pip install numpy
    /tmp/gsf-venv/bin/python scripts/convert_vgg16_weights.py \
        ../shared/weights/vgg16_imagenet_conv1_1-conv3_3.npz \
        crates/gs-features/weights/vgg16_conv3_3.f16.bin

Blob layout (all little-endian), read by crates/gs-features/src/weights.rs:
    magic      8 bytes  b"VGGF16\\0\\1"
    version    u32      1
    n_layers   u32      7
    mean       3 x f32  input mean (RGB, [0,1] scale)
    std        3 x f32  input std
    per layer: name 16 bytes (ASCII, zero padded), cout u32, cin u32, kh u32, kw u32
    per layer: weights cout*cin*kh*kw x f16 (OIHW, round-to-nearest-even from f32),
               then bias cout x f32 (kept f32: 1152 values in all)
    crc32      u32      zlib.crc32 of every preceding byte
"""
import struct, sys, zlib
import numpy as np

NAMES = ["conv1_1", "conv1_2", "conv2_1", "conv2_2", "conv3_1", "conv3_2", "conv3_3"]


def main(src, dst):
    z = np.load(src)
    out = bytearray(b"VGGF16\0\1")
    out += struct.pack("<II", 1, len(NAMES))
    out += np.asarray(z["input_mean"], "<f4").tobytes() + np.asarray(z["input_std"], "<f4").tobytes()
    for n in NAMES:
        w = z[n + "_weight"]
        assert w.ndim == 4 and w.shape[2:] == (3, 3), (n, w.shape)
        out += n.encode().ljust(16, b"\0") + struct.pack("<4I", *w.shape)
    for n in NAMES:
        w = np.ascontiguousarray(z[n + "_weight"], dtype="<f4")
        b = np.ascontiguousarray(z[n + "_bias"], dtype="<f4")
        assert b.shape == (w.shape[0],)
        out += w.astype("<f2").tobytes() + b.tobytes()
    out += struct.pack("<I", zlib.crc32(bytes(out)) & 0xFFFFFFFF)
    tmp = dst + ".tmp"
    with open(tmp, "wb") as f:
        f.write(out)
    import os
    os.replace(tmp, dst)
    print(f"wrote {dst}: {len(out)} bytes, crc32 {zlib.crc32(bytes(out[:-4])) & 0xFFFFFFFF:08x}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
