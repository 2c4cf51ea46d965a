#!/usr/bin/env python3
"""Convert the shared LPIPS-alex v0.1 weights (npz, float32) into the compact file bundled with
gs-losses: crates/gs-losses/weights/lpips_alex_v0.1.f16.bin.

Format (all little-endian):
    b"VGSLPW01"                      8-byte magic
    u32 n_tensors
    n_tensors times:
        u8 name_len, name (ASCII), u8 dtype (0 = f32, 1 = f16), u8 ndim, ndim x u32 dims, data
    u64 FNV-1a-64 of every preceding byte

The five conv weights are stored as IEEE half (round to nearest even, numpy astype); biases, the
linear heads and the scaling layer stay f32. Usage (numpy only):

    python3 scripts/lpips_weights_to_f16.py ../shared/weights/lpips_alex_v0.1.npz \
        crates/gs-losses/weights/lpips_alex_v0.1.f16.bin
"""
import os
import struct
import sys

import numpy as np

ORDER = [f"conv{i}_{k}" for i in range(1, 6) for k in ("weight", "bias")] + \
        [f"lin{i}_weight" for i in range(5)] + ["scaling_shift", "scaling_scale"]


def fnv1a64(data: bytes) -> int:
    h = 0xCBF29CE484222325
    prime = 0x100000001B3
    # Vectorised over 8-byte-free loop is not possible for FNV; plain loop (about 5 s for 5 MB).
    for b in data:
        h ^= b
        h = (h * prime) & 0xFFFFFFFFFFFFFFFF
    return h


def main(src, dst):
    z = np.load(src)
    out = bytearray(b"VGSLPW01")
    out += struct.pack("<I", len(ORDER))
    for name in ORDER:
        a = np.ascontiguousarray(z[name], dtype=np.float32)
        half = name.startswith("conv") and name.endswith("_weight")
        data = a.astype("<f2") if half else a.astype("<f4")
        if half and not np.all(np.isfinite(data)):
            raise SystemExit(f"{name}: value out of f16 range")
        out += struct.pack("<B", len(name)) + name.encode("ascii")
        out += struct.pack("<BB", 1 if half else 0, a.ndim)
        out += struct.pack(f"<{a.ndim}I", *a.shape)
        out += data.tobytes()
        err = np.abs(data.astype(np.float32) - a).max()
        print(f"{name:15s} {str(a.shape):18s} {'f16' if half else 'f32'} max abs rounding error {err:.3g}")
    out += struct.pack("<Q", fnv1a64(bytes(out)))
    tmp = dst + ".tmp"
    with open(tmp, "wb") as f:
        f.write(out)
    os.replace(tmp, dst)
    print(f"wrote {dst}: {len(out)} bytes, fnv1a64 {struct.unpack('<Q', out[-8:])[0]:016x}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    main(sys.argv[1], sys.argv[2])
