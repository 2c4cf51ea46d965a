//! υ·ω, L_p and L_f on GT-rendered views of vagsl's built-in scene (gs-synth: exact depth and
//! normals of the triangles the images were ray traced from).
//!
//! - Occlusion: for a reference/source pair where the objects hide part of the floor from the
//!   source, the exact ray-traced visibility (BVH) says which reference pixels the source sees
//!   and which it does not; υ·ω must be ≈ 1 on the first and 0 on the second.
//! - Signal: L_p (and L_f, with υω frozen as the synth-bunny reference README §4 explains) is
//!   lower at the GT geometry than with every plane 2 % farther or nearer.

use gs_core::glam::{DVec2, DVec3};
use gs_core::{Camera, Image, NeighbourRule, source_view_candidates};
use gs_mvs::{
    FeatureReference, FeatureSource, MapView, PhotometricConfig, PhotometricReference, PhotometricSource, Visibility,
    compute_visibility, feature_loss_with_weights, photometric_loss_with_weights,
};
use gs_synth::{BuiltinOptions, BuiltinScene, Bvh, generate};

fn builtin() -> BuiltinScene {
    generate(&BuiltinOptions { supersample: 1, ..Default::default() }).unwrap()
}

/// Camera-space normal Ñ and distance D = −Ñ·x of view `v` from its GT (0 where missed).
fn gt_plane(b: &BuiltinScene, v: usize) -> (Image, Image) {
    let cam = &b.scene.views[v].camera;
    let (w, h) = (cam.width as usize, cam.height as usize);
    let (mut n, mut d) = (Image::filled(w, h, 3, 0.0).unwrap(), Image::filled(w, h, 1, 0.0).unwrap());
    for j in 0..h {
        for i in 0..w {
            let z = b.gt_depth[v].get(i, j, 0) as f64;
            if z <= 0.0 {
                continue;
            }
            let nw = DVec3::new(
                b.gt_normals[v].get(i, j, 0) as f64,
                b.gt_normals[v].get(i, j, 1) as f64,
                b.gt_normals[v].get(i, j, 2) as f64,
            );
            let nc = (cam.rotation * nw).normalize();
            let x = cam.ray(i as f64 + 0.5, j as f64 + 0.5) * z;
            for c in 0..3 {
                n.set(i, j, c, nc[c] as f32);
            }
            d.set(i, j, 0, (-nc.dot(x)) as f32);
        }
    }
    (n, d)
}

/// Exact visibility of reference pixel (i, j) from `source`: `Some(true)` when the source sees
/// the surface point (first hit within 0.1 % of its distance) and the point projects away from
/// source depth discontinuities (all four bilinear taps of the source depth within 0.5 %),
/// `Some(false)` when something lies clearly (> 2 %) in front of it at all four taps, `None`
/// otherwise (outside the source, grazing, at an edge).
fn exact_visibility(b: &BuiltinScene, bvh: &Bvh, r: usize, s: usize, i: usize, j: usize) -> Option<bool> {
    let (cr, cs): (&Camera, &Camera) = (&b.scene.views[r].camera, &b.scene.views[s].camera);
    let z = b.gt_depth[r].get(i, j, 0) as f64;
    if z <= 0.0 {
        return None;
    }
    let x = cr.back_project(i as f64 + 0.5, j as f64 + 0.5, z);
    let (p, zs) = cs.project(x)?;
    let margin = DVec2::splat(1.0);
    if !(p.cmpge(margin).all() && p.cmplt(DVec2::new(cs.width as f64, cs.height as f64) - margin).all()) {
        return None;
    }
    let origin = cs.center();
    let dist = (x - origin).length();
    let hit = bvh.intersect(origin, (x - origin) / dist, 1e-6, dist * 1.01)?;
    let (u0, v0) = ((p.x - 0.5).floor() as usize, (p.y - 0.5).floor() as usize);
    let taps = [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(a, c)| b.gt_depth[s].get(u0 + a, v0 + c, 0) as f64 / zs);
    if hit.t < 0.98 * dist {
        // Occluded, and not at the occluder's silhouette (where the bilinear source depth
        // blends occluder and background): every tap is clearly in front.
        return taps.iter().all(|&t| t < 0.98).then_some(false);
    }
    if hit.t < 0.999 * dist {
        return None;
    }
    taps.iter().all(|&t| (t - 1.0).abs() < 0.005).then_some(true)
}

#[test]
fn upsilon_omega_is_one_where_visible_and_zero_where_occluded() {
    let b = builtin();
    let bvh = Bvh::new(&b.scene_mesh).unwrap();
    let cams: Vec<&Camera> = b.scene.views.iter().map(|v| &v.camera).collect();
    let cands = source_view_candidates(&cams, &NeighbourRule::default());
    // The pair (reference, nearest source) with the most occluded reference pixels.
    let (w, h) = (cams[0].width as usize, cams[0].height as usize);
    /// (reference, source, labelled pixels, occluded count) of the best pair so far.
    type Pair = (usize, usize, Vec<(usize, bool)>, usize);
    let mut best: Option<Pair> = None;
    for (r, c) in cands.iter().enumerate().step_by(3) {
        let Some(&s) = c.first() else { continue };
        let labels: Vec<(usize, bool)> = (0..w * h)
            .filter_map(|p| exact_visibility(&b, &bvh, r, s, p % w, p / w).map(|v| (p, v)))
            .collect();
        let occluded = labels.iter().filter(|l| !l.1).count();
        if best.as_ref().is_none_or(|bb| occluded > bb.3) {
            best = Some((r, s, labels, occluded));
        }
    }
    let (r, s, labels, _) = best.unwrap();
    let vis = compute_visibility(
        cams[r],
        (&b.gt_depth[r]).into(),
        cams[s],
        (&b.gt_depth[s]).into(),
    )
    .unwrap();
    let visible: Vec<f32> = labels.iter().filter(|l| l.1).map(|l| vis.weight(l.0)).collect();
    let occluded: Vec<f32> = labels.iter().filter(|l| !l.1).map(|l| vis.weight(l.0)).collect();
    let mean = visible.iter().map(|&v| v as f64).sum::<f64>() / visible.len() as f64;
    let high = visible.iter().filter(|&&v| v > 0.9).count() as f64 / visible.len() as f64;
    let leaked = occluded.iter().filter(|&&v| v > 0.0).count();
    println!(
        "reference {r}, source {s}: {} mutually visible pixels, mean υω {mean:.4}, {:.1} % > 0.9; {} occluded, {leaked} with ω > 0",
        visible.len(),
        100.0 * high,
        occluded.len()
    );
    assert!(visible.len() > 10_000, "too few mutually visible pixels: {}", visible.len());
    assert!(occluded.len() > 300, "the chosen pair has only {} occluded pixels", occluded.len());
    assert!(mean > 0.95 && high > 0.9, "υω on mutually visible pixels: mean {mean}, {high} above 0.9");
    assert_eq!(leaked, 0, "ω > 0 on {leaked} of {} occluded pixels", occluded.len());
}

#[test]
fn gt_geometry_beats_two_percent_depth_error() {
    let b = builtin();
    let cams: Vec<&Camera> = b.scene.views.iter().map(|v| &v.camera).collect();
    let cands = source_view_candidates(&cams, &NeighbourRule::default());
    let r = 5;
    let sources: Vec<usize> = cands[r].iter().take(3).copied().collect();
    assert_eq!(sources.len(), 3);
    let (w, h) = (cams[r].width as usize, cams[r].height as usize);
    let (n, d) = gt_plane(&b, r);
    let greys: Vec<Image> = b.scene.views.iter().map(|v| v.image.to_grey().unwrap()).collect();
    let weights: Vec<Visibility<f32>> = sources
        .iter()
        .map(|&s| compute_visibility(cams[r], (&b.gt_depth[r]).into(), cams[s], (&b.gt_depth[s]).into()).unwrap())
        .collect();
    let cfg = PhotometricConfig { max_pixels_per_source: None, ..Default::default() };
    let net = gs_features::Vgg16::bundled().unwrap();
    let feats: Vec<gs_features::FeatureMap> = std::iter::once(r)
        .chain(sources.iter().copied())
        .map(|v| net.extract(&b.scene.views[v].image, gs_features::FeatureLevel::Conv2_2).unwrap())
        .collect();
    let losses = |scale: f32| -> (f64, f64) {
        let dist: Vec<f32> = d.data().iter().map(|v| v * scale).collect();
        // Plane depth scales with D.
        let z: Vec<f32> = b.gt_depth[r].data().iter().map(|v| v * scale).collect();
        let reference = PhotometricReference {
            camera: cams[r],
            normal: (&n).into(),
            distance: MapView::new(w, h, 1, &dist).unwrap(),
            plane_depth: MapView::new(w, h, 1, &z).unwrap(),
            grey: (&greys[r]).into(),
        };
        let srcs: Vec<PhotometricSource<f32>> = sources
            .iter()
            .map(|&s| PhotometricSource { camera: cams[s], plane_depth: (&b.gt_depth[s]).into(), grey: (&greys[s]).into() })
            .collect();
        let lp = photometric_loss_with_weights(&reference, &srcs, &weights, &cfg).unwrap();
        assert!(lp.per_source.iter().all(|p| p.n_valid > 2000), "{:?}", lp.per_source);
        let fr = FeatureReference { camera: cams[r], plane_depth: MapView::new(w, h, 1, &z).unwrap(), features: &feats[0] };
        let fs: Vec<FeatureSource<f32>> = sources
            .iter()
            .zip(&feats[1..])
            .map(|(&s, f)| FeatureSource { camera: cams[s], plane_depth: (&b.gt_depth[s]).into(), features: f })
            .collect();
        let lf = feature_loss_with_weights(&fr, &fs, &weights).unwrap();
        (lp.loss, lf.loss)
    };
    let (lp0, lf0) = losses(1.0);
    println!("GT: L_p {lp0:.5}, L_f {lf0:.5}");
    for scale in [1.02f32, 0.98] {
        let (lp, lf) = losses(scale);
        println!("D × {scale}: L_p {lp:.5}, L_f {lf:.5}");
        assert!(lp0 < lp, "L_p: GT {lp0} vs ×{scale} {lp}");
        assert!(lf0 < lf, "L_f: GT {lf0} vs ×{scale} {lf}");
    }
}
