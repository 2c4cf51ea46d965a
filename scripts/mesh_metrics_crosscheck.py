"""Independent reference for gs-tsdf's point metrics (scipy cKDTree, float64).

Writes crates/gs-tsdf/tests/fixtures/metrics_points.f64 (pred then GT points, little-endian
float64 xyz, with a 16-byte header of the two counts as uint64) and metrics_scipy.json
(accuracy / completeness / Chamfer / precision / recall / F1 at tau, with and without a clamp).
The test `metrics_match_scipy` in crates/gs-tsdf/tests/metrics_crosscheck.rs reads both.

    python3 -m venv /tmp/v && /tmp/v/bin/pip install numpy scipy
    /tmp/v/bin/python scripts/mesh_metrics_crosscheck.py
"""
import json, os
import numpy as np
from scipy.spatial import cKDTree

rng = np.random.default_rng(20261123)
def sphere(n, r):
    v = rng.normal(size=(n, 3)); return r * v / np.linalg.norm(v, axis=1, keepdims=True)
gt = sphere(4000, 1.0)
pred = sphere(3000, 1.0) + rng.normal(scale=0.01, size=(3000, 3))
pred[:50] += rng.uniform(-0.5, 0.5, size=(50, 3))   # outliers
gt = gt[gt[:, 2] > -0.8]                              # a hole in the prediction's view of GT
out = os.path.join(os.path.dirname(__file__), "..", "crates", "gs-tsdf", "tests", "fixtures")
with open(os.path.join(out, "metrics_points.f64"), "wb") as f:
    f.write(np.array([len(pred), len(gt)], dtype="<u8").tobytes())
    f.write(pred.astype("<f8").tobytes()); f.write(gt.astype("<f8").tobytes())
d_pg = cKDTree(gt).query(pred)[0]; d_gp = cKDTree(pred).query(gt)[0]
def metrics(tau, clamp):
    a = np.minimum(d_pg, clamp).mean(); c = np.minimum(d_gp, clamp).mean()
    p = (d_pg < tau).mean(); r = (d_gp < tau).mean()
    return dict(accuracy=a, completeness=c, chamfer=(a + c) / 2, precision=p, recall=r,
                f1=2 * p * r / (p + r) if p + r > 0 else 0.0, tau=tau)
ref = {"plain": metrics(0.02, np.inf), "clamped": metrics(0.05, 0.1)}
ref["clamped"]["max_distance"] = 0.1
json.dump(ref, open(os.path.join(out, "metrics_scipy.json"), "w"), indent=1, default=float)
print(json.dumps(ref, indent=1, default=float))
