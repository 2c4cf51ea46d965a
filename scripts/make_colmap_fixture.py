#!/usr/bin/env python3
"""Build the COLMAP binary fixture of gs-io from a reduced synth-bunny model.

1. Reads ../shared/data/synth-bunny/sparse/0 (TEXT), keeps the first 6 images and the first
   200 points (by id) seen by them; tracks are restricted to the kept images, each kept
   image keeps the observations of kept points plus up to 8 observations of dropped
   points as unassigned keypoints (POINT3D_ID -1), with point2D indices renumbered.
   Two extra cameras make the binary layout cover more models: image 2 uses an OPENCV
   camera and image 3 a FULL_OPENCV one (small made-up distortion), the rest the original
   PINHOLE camera.
2. Writes that reduced model as TEXT to crates/gs-io/tests/fixtures/colmap/text/.
3. Lets pycolmap (real COLMAP) read the text and write its BINARY model to
   crates/gs-io/tests/fixtures/colmap/pycolmap_bin/ (only cameras/images/points3D.bin are
   kept; pycolmap >= 3.12 also writes rigs.bin and frames.bin, which gs-io does not use).

Run once in a throw-away venv:
    python3 -m venv /tmp/pycm && /tmp/pycm/bin/pip install pycolmap numpy
    /tmp/pycm/bin/python scripts/make_colmap_fixture.py
"""
import os
import shutil
import sys
import tempfile

import pycolmap

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SRC = os.path.join(ROOT, "..", "shared", "data", "synth-bunny", "sparse", "0")
OUT = os.path.join(ROOT, "crates", "gs-io", "tests", "fixtures", "colmap")
N_IMAGES = 6
N_POINTS = 200
N_UNASSIGNED = 8


def data_lines(path):
    with open(path) as f:
        return [l.rstrip("\n") for l in f if not l.startswith("#")]


def main():
    cams = {}
    for l in data_lines(os.path.join(SRC, "cameras.txt")):
        if l.strip():
            t = l.split()
            cams[int(t[0])] = (t[1], int(t[2]), int(t[3]), [float(x) for x in t[4:]])

    lines = data_lines(os.path.join(SRC, "images.txt"))
    images = {}
    for i in range(0, len(lines) - 1, 2):
        t = lines[i].split()
        if not t:
            continue
        pts = lines[i + 1].split()
        obs = [(float(pts[k]), float(pts[k + 1]), int(pts[k + 2])) for k in range(0, len(pts), 3)]
        images[int(t[0])] = ([float(x) for x in t[1:8]], int(t[8]), t[9], obs)

    points = {}
    for l in data_lines(os.path.join(SRC, "points3D.txt")):
        t = l.split()
        if not t:
            continue
        track = [(int(t[k]), int(t[k + 1])) for k in range(8, len(t), 2)]
        points[int(t[0])] = ([float(x) for x in t[1:4]], [int(x) for x in t[4:7]], float(t[7]), track)

    kept_images = sorted(images)[:N_IMAGES]
    kept_set = set(kept_images)
    kept_points = [pid for pid in sorted(points) if any(im in kept_set for im, _ in points[pid][3])][:N_POINTS]
    kept_pset = set(kept_points)

    # Rebuild each kept image's POINTS2D and remember the new indices.
    new_obs = {}
    index_map = {}
    for im in kept_images:
        obs = []
        unassigned = 0
        for old_idx, (x, y, pid) in enumerate(images[im][3]):
            if pid in kept_pset:
                index_map[(im, old_idx)] = len(obs)
                obs.append((x, y, pid))
            elif unassigned < N_UNASSIGNED:
                unassigned += 1
                obs.append((x, y, -1))
        new_obs[im] = obs

    # Extra cameras with made-up distortion for binary-layout coverage.
    model, w, h, p = cams[1]
    assert model == "PINHOLE"
    fx, fy, cx, cy = p
    cams_out = {
        1: ("PINHOLE", w, h, p),
        2: ("OPENCV", w, h, [fx, fy, cx, cy, -0.05, 0.01, 0.001, -0.0005]),
        3: ("FULL_OPENCV", w, h, [fx, fy, cx, cy, -0.1, 0.02, 0.0005, 0.0002, 0.001, 0.01, -0.002, 0.0001]),
    }
    cam_of = {im: 1 for im in kept_images}
    cam_of[kept_images[1]] = 2
    cam_of[kept_images[2]] = 3

    text_dir = os.path.join(OUT, "text")
    os.makedirs(text_dir, exist_ok=True)
    with open(os.path.join(text_dir, "cameras.txt"), "w") as f:
        f.write("# Reduced synth-bunny model for gs-io tests (scripts/make_colmap_fixture.py)\n")
        for cid, (m, w, h, p) in cams_out.items():
            f.write(f"{cid} {m} {w} {h} " + " ".join(repr(x) for x in p) + "\n")
    with open(os.path.join(text_dir, "images.txt"), "w") as f:
        f.write("# IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME / POINTS2D[] as (X, Y, POINT3D_ID)\n")
        for im in kept_images:
            pose, _, name, _ = images[im]
            f.write(f"{im} " + " ".join(repr(x) for x in pose) + f" {cam_of[im]} {name}\n")
            f.write(" ".join(f"{x!r} {y!r} {pid}" for x, y, pid in new_obs[im]) + "\n")
    with open(os.path.join(text_dir, "points3D.txt"), "w") as f:
        f.write("# POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n")
        for pid in kept_points:
            xyz, rgb, err, track = points[pid]
            tr = [(im, index_map[(im, idx)]) for im, idx in track if im in kept_set]
            f.write(f"{pid} " + " ".join(repr(x) for x in xyz) + " " + " ".join(map(str, rgb))
                    + f" {err!r} " + " ".join(f"{im} {idx}" for im, idx in tr) + "\n")

    rec = pycolmap.Reconstruction(text_dir)
    print(rec.summary())
    bin_dir = os.path.join(OUT, "pycolmap_bin")
    os.makedirs(bin_dir, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        rec.write_binary(tmp)
        print("pycolmap wrote:", sorted(os.listdir(tmp)))
        for name in ("cameras.bin", "images.bin", "points3D.bin"):
            shutil.copy(os.path.join(tmp, name), os.path.join(bin_dir, name))
    print("pycolmap", pycolmap.__version__, "->", bin_dir)
    return 0


if __name__ == "__main__":
    sys.exit(main())
