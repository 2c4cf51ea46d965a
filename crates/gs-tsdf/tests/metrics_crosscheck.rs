//! `point_metrics` (and so `vagsl eval-mesh`) against an independent computation: scipy's
//! cKDTree in float64 on fixed point sets (`scripts/mesh_metrics_crosscheck.py` wrote the
//! fixture and the reference values). Agreement to 1e-6 relative.

use gs_tsdf::point_metrics;

fn fixture() -> (Vec<[f64; 3]>, Vec<[f64; 3]>, serde_json::Value) {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let bytes = std::fs::read(dir.join("metrics_points.f64")).unwrap();
    let n_pred = u64::from_le_bytes(bytes[0..8].try_into().unwrap()) as usize;
    let n_gt = u64::from_le_bytes(bytes[8..16].try_into().unwrap()) as usize;
    let vals: Vec<f64> = bytes[16..].chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap())).collect();
    assert_eq!(vals.len(), 3 * (n_pred + n_gt));
    let pts: Vec<[f64; 3]> = vals.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    let reference = serde_json::from_str(&std::fs::read_to_string(dir.join("metrics_scipy.json")).unwrap()).unwrap();
    (pts[..n_pred].to_vec(), pts[n_pred..].to_vec(), reference)
}

#[test]
fn metrics_match_scipy() {
    let (pred, gt, reference) = fixture();
    for (key, clamp) in [("plain", None), ("clamped", Some(0.1))] {
        let r = &reference[key];
        let tau = r["tau"].as_f64().unwrap();
        let m = point_metrics(&pred, &gt, tau, clamp).unwrap();
        for (name, ours) in [
            ("accuracy", m.accuracy),
            ("completeness", m.completeness),
            ("chamfer", m.chamfer),
            ("precision", m.precision),
            ("recall", m.recall),
            ("f1", m.f1),
        ] {
            let theirs = r[name].as_f64().unwrap();
            let rel = (ours - theirs).abs() / theirs.abs().max(1e-300);
            assert!(rel < 1e-6, "{key} {name}: ours {ours} vs scipy {theirs} (rel {rel:e})");
        }
    }
}
