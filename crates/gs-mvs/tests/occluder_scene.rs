//! υ/ω on a scene with a known occluder, and the extremes of docs/architecture.md §Extremes for L_p.

use gs_core::glam::DVec3;
use gs_core::{Camera, Image, Intrinsics, NeighbourRule, Rng};
use gs_mvs::analytic_scene::{AnalyticScene, AxisBox};
use gs_mvs::{
    MapView, NccMode, PhotometricConfig, PhotometricReference, PhotometricSource, SourceSelection,
    SourceViewSelector, compute_visibility, photometric_loss,
};

fn scene() -> AnalyticScene {
    AnalyticScene {
        boxes: vec![AxisBox {
            min: DVec3::new(-0.3, -0.3, 0.0),
            max: DVec3::new(0.3, 0.3, 0.8),
        }],
        frequency: 6.0,
    }
}

fn camera(eye: DVec3, w: u32, h: u32) -> Camera {
    let f = w as f64 * 0.8;
    Camera::look_at(
        w,
        h,
        Intrinsics::new(f, f, w as f64 / 2.0, h as f64 / 2.0),
        eye,
        DVec3::new(0.0, 0.0, 0.2),
        DVec3::Z,
    )
    .unwrap()
}

/// υ·ω ≈ 1 on mutually visible surface pixels and 0 on pixels occluded in the source, with the
/// ground truth decided by exact ray casting.
#[test]
fn occlusion_weight_on_a_known_occluder() {
    let sc = scene();
    let r = camera(DVec3::new(-0.9, -2.6, 1.8), 120, 90);
    let s = camera(DVec3::new(0.9, -2.6, 1.8), 120, 90);
    let (mr, ms) = (sc.render(&r), sc.render(&s));
    let vis =
        compute_visibility(&r, (&mr.plane_depth).into(), &s, (&ms.plane_depth).into()).unwrap();
    let (mut mutual, mut occluded) = (Vec::new(), Vec::new());
    for j in 0..90usize {
        for i in 0..120usize {
            let z = mr.depth.get(i, j, 0) as f64;
            if z <= 0.0 {
                continue;
            }
            let x = r.back_project(i as f64 + 0.5, j as f64 + 0.5, z);
            let Some((p, zs)) = s.project(x) else {
                continue;
            };
            if !(p.x > 1.0 && p.y > 1.0 && p.x < 119.0 && p.y < 89.0) {
                continue;
            }
            // Camera z of the first hit along the source ray through (u, v) (the ray has z = 1).
            let hit = |u: f64, v: f64| {
                sc.cast(s.center(), s.rotation.transpose() * s.ray(u, v))
                    .map_or(f64::INFINITY, |(t, _)| t)
            };
            let z_hit = hit(p.x, p.y);
            let w = vis.weight(j * 120 + i) as f64;
            // Occluded: the surface in front is also in front 1.5 px around p, so the depth map
            // (sampled at pixel centres, read bilinearly) resolves the occluder there too.
            let ring = [
                (1.5, 0.0),
                (-1.5, 0.0),
                (0.0, 1.5),
                (0.0, -1.5),
                (1.5, 1.5),
                (-1.5, -1.5),
                (1.5, -1.5),
                (-1.5, 1.5),
            ];
            if (z_hit - zs).abs() < 1e-4 * zs {
                mutual.push(w);
            } else if z_hit < 0.98 * zs
                && ring
                    .iter()
                    .all(|(du, dv)| hit(p.x + du, p.y + dv) < 0.98 * zs)
            {
                occluded.push(w);
            }
        }
    }
    assert!(
        mutual.len() > 3000 && occluded.len() > 200,
        "{} mutual, {} occluded",
        mutual.len(),
        occluded.len()
    );
    let mean = mutual.iter().sum::<f64>() / mutual.len() as f64;
    let above = mutual.iter().filter(|&&w| w > 0.9).count() as f64 / mutual.len() as f64;
    assert!(
        mean > 0.95 && above > 0.93,
        "mutual: mean υω {mean}, fraction > 0.9: {above}"
    );
    let max_occ = occluded.iter().copied().fold(0.0f64, f64::max);
    println!(
        "mutual {} (mean υω {mean:.4}, {above:.4} > 0.9), occluded {} (max ω {max_occ})",
        mutual.len(),
        occluded.len()
    );
    assert_eq!(max_occ, 0.0, "ω on occluded pixels");
    let st = vis.stats();
    assert!(st.n_omega_positive < st.n_upsilon);
}

fn grid_camera_pair(w: u32, h: u32) -> (Camera, Camera, Camera) {
    (
        camera(DVec3::new(0.0, -2.6, 1.8), w, h),
        camera(DVec3::new(0.4, -2.6, 1.8), w, h),
        camera(DVec3::new(-0.5, -2.5, 1.9), w, h),
    )
}

/// Grazing planes, D → 0 and D < 0, w_z → 0 or < 0, NaN/∞ maps, constant images and no
/// neighbours: finite loss and gradients, no panic.
#[test]
fn extremes_are_finite() {
    let (w, h) = (48usize, 36usize);
    let (r, s1, s2) = grid_camera_pair(w as u32, h as u32);
    let sc = scene();
    let (mr, m1, m2) = (sc.render(&r), sc.render(&s1), sc.render(&s2));
    let mut rng = Rng::new(5);
    let mut normal = mr.normal.clone();
    let mut distance = mr.distance.clone();
    let mut plane = mr.plane_depth.clone();
    for j in 0..h {
        for i in 0..w {
            let ray = r.ray(i as f64 + 0.5, j as f64 + 0.5).as_vec3();
            match (i + 7 * j) % 9 {
                // Grazing: n ⟂ ray, plane depth = D / 1e-8.
                0 => {
                    let n = ray.cross(gs_core::glam::Vec3::X).normalize();
                    normal.pixel_mut(i, j).copy_from_slice(&n.to_array());
                    plane.set(i, j, 0, distance.get(i, j, 0) / 1e-8);
                }
                1 => distance.set(i, j, 0, 1e-30),
                2 => distance.set(i, j, 0, 0.0),
                3 => distance.set(i, j, 0, -0.5),
                // Random planes: w_z of some samples near or below 0.
                4 => {
                    for c in 0..3 {
                        normal.set(i, j, c, rng.uniform_range(-3.0, 3.0));
                    }
                    distance.set(i, j, 0, rng.uniform_range(-1e-3, 1e-3));
                }
                5 if i % 5 == 0 => normal.set(i, j, 1, f32::NAN),
                6 if i % 5 == 0 => distance.set(i, j, 0, f32::INFINITY),
                7 if i % 5 == 0 => plane.set(i, j, 0, f32::NAN),
                _ => {}
            }
        }
    }
    let flat = Image::filled(w, h, 1, 0.5).unwrap();
    for grey_case in 0..2 {
        let (gr, g1, g2) = if grey_case == 0 {
            (&mr.grey, &m1.grey, &m2.grey)
        } else {
            (&flat, &flat, &flat)
        };
        let reference = PhotometricReference {
            camera: &r,
            normal: (&normal).into(),
            distance: (&distance).into(),
            plane_depth: (&plane).into(),
            grey: gr.into(),
        };
        let sources = [
            PhotometricSource {
                camera: &s1,
                plane_depth: (&m1.plane_depth).into(),
                grey: g1.into(),
            },
            PhotometricSource {
                camera: &s2,
                plane_depth: (&m2.plane_depth).into(),
                grey: g2.into(),
            },
        ];
        for ncc in [NccMode::Pgsr, NccMode::Plain] {
            let cfg = PhotometricConfig {
                ncc,
                ..Default::default()
            };
            let out = photometric_loss(&reference, &sources, &cfg).unwrap();
            assert!(
                out.loss.is_finite(),
                "{ncc:?} case {grey_case}: {}",
                out.loss
            );
            assert!(
                out.grad_normal
                    .iter()
                    .chain(&out.grad_distance)
                    .all(|g| g.is_finite())
            );
            if grey_case == 1 {
                match ncc {
                    // Constant patches: cost 1 ≥ 0.9, all masked.
                    NccMode::Pgsr => {
                        assert!(out.per_source.iter().all(|s| s.n_valid == 0) && out.loss == 0.0)
                    }
                    // Plain: cost 1 with zero gradient.
                    NccMode::Plain => {
                        assert!(out.per_source.iter().all(|s| s.n_valid > 0
                            && (s.loss * s.n_valid as f64 - s.weighted_cost_sum).abs() < 1e-6));
                        assert!(
                            out.grad_normal
                                .iter()
                                .chain(&out.grad_distance)
                                .all(|&g| g == 0.0)
                        );
                    }
                }
            }
        }
        // No neighbours: no sources, L_p = 0.
        let none = photometric_loss(&reference, &[], &PhotometricConfig::default()).unwrap();
        assert_eq!(none.loss, 0.0);
        assert!(none.per_source.is_empty() && none.grad_distance.iter().all(|&g| g == 0.0));
    }
    // A 1×1 reference (no interior pixel for a 7×7 patch) and a source behind the reference.
    let tiny_img = Image::filled(1, 1, 1, 1.0).unwrap();
    let tiny_n = Image::filled(1, 1, 3, -0.5).unwrap();
    let tiny = r.resized(1, 1).unwrap();
    let reference = PhotometricReference {
        camera: &tiny,
        normal: (&tiny_n).into(),
        distance: (&tiny_img).into(),
        plane_depth: (&tiny_img).into(),
        grey: (&tiny_img).into(),
    };
    let behind = camera(DVec3::new(0.0, 2.6, 1.8), w as u32, h as u32);
    let src = [PhotometricSource {
        camera: &behind,
        plane_depth: (&m1.plane_depth).into(),
        grey: (&m1.grey).into(),
    }];
    let out = photometric_loss(&reference, &src, &PhotometricConfig::default()).unwrap();
    assert_eq!(out.loss, 0.0);
    // A view with no neighbours gets no sources from the selector.
    let sel = SourceViewSelector::new(
        &[&r, &behind],
        &NeighbourRule::default(),
        3,
        SourceSelection::RandomN,
    )
    .unwrap();
    assert!(sel.select(0, &mut Rng::new(1)).is_empty());
    // Mismatched sizes are an error, not a panic.
    let wrong = [PhotometricSource {
        camera: &s1,
        plane_depth: MapView::from(&tiny_img),
        grey: (&m1.grey).into(),
    }];
    let reference = PhotometricReference {
        camera: &r,
        normal: (&mr.normal).into(),
        distance: (&mr.distance).into(),
        plane_depth: (&mr.plane_depth).into(),
        grey: (&mr.grey).into(),
    };
    let err = photometric_loss(&reference, &wrong, &PhotometricConfig::default()).unwrap_err();
    assert!(err.to_string().contains("source 0 plane_depth"), "{err}");
}
