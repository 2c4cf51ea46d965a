#!/usr/bin/env python3
"""Checks that a Gaussian PLY written by vagsl (gs-io) parses with Python `plyfile`, the
library the original Inria 3DGS code uses, and lists the Inria property names.

Usage (throw-away venv, never inside the repo):
    python3 -m venv /tmp/plyvenv && /tmp/plyvenv/bin/pip install plyfile numpy
    /tmp/plyvenv/bin/python scripts/check_ply_plyfile.py \
        crates/gs-io/tests/fixtures/ply/gaussians_small.ply \
        > crates/gs-io/tests/fixtures/ply/plyfile_check_output.txt

The output is committed as a fixture; the Rust test `golden_fixture_matches_the_writer`
(crates/gs-io/tests/ply_gaussian.rs) checks that it lists the writer's property names.
Exits non-zero if the layout differs from the one Inria's `GaussianModel.load_ply` expects.
"""
import importlib.metadata
import sys

import numpy as np
from plyfile import PlyData


def inria_names(rest):
    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
    names += [f"f_rest_{i}" for i in range(rest)]
    names += ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    return names


def main(path):
    ply = PlyData.read(path)
    vertex = ply["vertex"]
    names = [p.name for p in vertex.properties]
    print(f"plyfile version: {importlib.metadata.version('plyfile')}")
    fmt = "ascii" if ply.text else {"<": "binary_little_endian", ">": "binary_big_endian"}.get(ply.byte_order, ply.byte_order)
    print(f"format: {fmt}")
    print(f"comments: {ply.comments}")
    print(f"elements: {' '.join(e.name for e in ply.elements)}")
    print(f"vertex count: {vertex.count}")
    print(f"properties: {' '.join(names)}")
    print(f"types: {sorted(set(str(vertex.data.dtype[n]) for n in names))}")
    ok = names == inria_names(45)
    # What Inria's load_ply does: f_rest reshaped to (N, 3, 15), channel-major.
    extra = np.stack([np.asarray(vertex[f"f_rest_{i}"]) for i in range(45)], axis=1).reshape(-1, 3, 15)
    print(f"gaussian 1 f_rest_15: {vertex['f_rest_15'][1]}")
    print(f"gaussian 1 G coefficient 1 via Inria reshape: {extra[1, 1, 0]}")
    print(f"inria layout: {'OK' if ok else 'MISMATCH'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
