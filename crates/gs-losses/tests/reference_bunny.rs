//! Reproduces the single-view values of `shared/data/synth-bunny/reference/values.json`
//! (method-spec §5.1–5.3; independent PyTorch float64 implementation, `tools/loss_reference.py`):
//! L1, SSIM, edge term, L_I, ∇I / δ means, L_nc for the GT and the 5°-rotated normal, L_ns with
//! both gates and both pair rules (with active-pair counts), and ∂L_nc/∂z (L2 norm, probes).
//! The f64 kernels are compared at the reference's recommended 1e-9 relative tolerance, the f32
//! `Image` APIs at its f32 tolerances.

mod common;

use common::shared;
use gs_core::camera::rotation_from_quaternion;
use gs_core::{Image, Intrinsics};
use gs_losses::gradient::{edge_l1, edge_weight, image_gradient, mean};
use gs_losses::l1::l1;
use gs_losses::normal::{depth_normal, depth_normal_backward};
use gs_losses::normal_loss::{normal_consistency, normal_smoothing};
use gs_losses::npy::read_npy;
use gs_losses::ssim::ssim;
use gs_losses::{Dims, EdgeGuide, ImageLossConfig, NormalLossConfig, NsGate, NsPairs, SsimRegion};
use serde_json::Value;

struct Bunny {
    w: usize,
    h: usize,
    k: Intrinsics,
    img: Vec<f64>,
    rendered: Vec<f64>,
    z: Vec<f64>,
    n_cam: Vec<f64>,
    reference: Value,
}

fn load() -> Bunny {
    let root = shared("data/synth-bunny");
    // The shared data lies beside the clone in CI and here: its absence is a failure, not a skip.
    assert!(root.exists(), "{} not found (the tests read ../shared beside the clone)", root.display());
    let reference: Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("reference/values.json")).unwrap())
            .unwrap();
    // Intrinsics and the pose of view 0008 from the COLMAP text model.
    let cams = std::fs::read_to_string(root.join("sparse/0/cameras.txt")).unwrap();
    let cam: Vec<f64> = cams
        .lines()
        .find(|l| !l.starts_with('#') && !l.trim().is_empty())
        .unwrap()
        .split_whitespace()
        .skip(4)
        .map(|v| v.parse().unwrap())
        .collect();
    let k = Intrinsics::new(cam[0], cam[1], cam[2], cam[3]);
    let imgs = std::fs::read_to_string(root.join("sparse/0/images.txt")).unwrap();
    let line = imgs
        .lines()
        .find(|l| l.trim_end().ends_with(" 0008.png"))
        .unwrap();
    let f: Vec<f64> = line
        .split_whitespace()
        .skip(1)
        .take(4)
        .map(|v| v.parse().unwrap())
        .collect();
    let r = rotation_from_quaternion([f[0], f[1], f[2], f[3]]).unwrap();
    let (w, h, rgb) = common::load_rgb8(&root.join("images/0008.png"));
    let img: Vec<f64> = rgb.iter().map(|&v| v as f64 / 255.0).collect();
    // Ĩ = 5×5 box blur (replicate border) × 0.95.
    let mut rendered = vec![0.0; img.len()];
    for j in 0..h {
        for i in 0..w {
            for c in 0..3 {
                let mut s = 0.0;
                for dj in -2i64..=2 {
                    for di in -2i64..=2 {
                        let jj = (j as i64 + dj).clamp(0, h as i64 - 1) as usize;
                        let ii = (i as i64 + di).clamp(0, w as i64 - 1) as usize;
                        s += img[(jj * w + ii) * 3 + c];
                    }
                }
                rendered[(j * w + i) * 3 + c] = s / 25.0 * 0.95;
            }
        }
    }
    let z = read_npy(&root.join("gt/depth_0008.npy")).unwrap();
    assert_eq!(z.shape, vec![h, w]);
    let nw = read_npy(&root.join("gt/normal_0008.npy")).unwrap();
    assert_eq!(nw.shape, vec![h, w, 3]);
    let mut n_cam = vec![0.0; w * h * 3];
    for p in 0..w * h {
        let v =
            r * gs_core::glam::DVec3::new(nw.data[3 * p], nw.data[3 * p + 1], nw.data[3 * p + 2]);
        let v = v / v.length();
        n_cam[3 * p..3 * p + 3].copy_from_slice(&[v.x, v.y, v.z]);
    }
    Bunny {
        w,
        h,
        k,
        img,
        rendered,
        z: z.data,
        n_cam,
        reference,
    }
}

fn num(v: &Value, path: &[&str]) -> f64 {
    let mut x = v;
    for p in path {
        x = &x[*p];
    }
    x.as_f64().unwrap_or_else(|| panic!("missing {path:?}"))
}

fn close(name: &str, ours: f64, theirs: f64, rel: f64, abs: f64) {
    let err = (ours - theirs).abs();
    assert!(
        err <= abs + rel * theirs.abs(),
        "{name}: ours {ours:.12e}, reference {theirs:.12e} (diff {err:.3e})"
    );
}

fn rot_x(n: &[f64], deg: f64) -> Vec<f64> {
    let (s, c) = deg.to_radians().sin_cos();
    n.chunks(3)
        .flat_map(|v| [v[0], c * v[1] - s * v[2], s * v[1] + c * v[2]])
        .collect()
}

#[test]
fn single_view_values_f64() {
    let b = load();
    let (w, h) = (b.w, b.h);
    let sv = &b.reference["float64"]["single_view"];
    let dims = Dims::new(w, h, 3);
    let rel = 1e-9;
    let l1v = l1(&b.rendered, &b.img);
    close("L1", l1v, num(sv, &["L1"]), rel, 0.0);
    let s = ssim(&b.rendered, &b.img, dims, SsimRegion::Full).unwrap();
    close("SSIM", s, num(sv, &["SSIM"]), rel, 0.0);
    let gi = image_gradient(&b.img, dims);
    let git = image_gradient(&b.rendered, dims);
    close(
        "gradI_raw_max",
        gi.max,
        num(sv, &["gradI_raw_max"]),
        rel,
        0.0,
    );
    close(
        "gradI_raw_min",
        gi.min,
        num(sv, &["gradI_raw_min"]),
        0.0,
        1e-15,
    );
    close(
        "gradI_mean",
        mean(&gi.map),
        num(sv, &["gradI_mean"]),
        rel,
        0.0,
    );
    close(
        "gradI_tilde_mean",
        mean(&git.map),
        num(sv, &["gradI_tilde_mean"]),
        rel,
        0.0,
    );
    let e = edge_l1(&git.map, &gi.map, 0.0, None);
    close("edge_L1", e, num(sv, &["edge_L1"]), rel, 0.0);
    close(
        "L_I",
        0.8 * l1v + 0.2 * (1.0 - s) + 0.03 * e,
        num(sv, &["L_I"]),
        rel,
        0.0,
    );
    let delta = edge_weight(&gi.map);
    close(
        "delta_mean",
        mean(&delta),
        num(sv, &["delta_mean"]),
        rel,
        0.0,
    );

    let nhat = depth_normal(&b.z, w, h, &b.k, None);
    let interior: f64 = (1..h - 1)
        .flat_map(|j| (1..w - 1).map(move |i| j * w + i))
        .map(|p| {
            (0..3)
                .map(|c| (nhat[3 * p + c] - b.n_cam[3 * p + c]).abs())
                .sum::<f64>()
        })
        .sum::<f64>()
        / ((w - 2) * (h - 2)) as f64;
    close(
        "Nhat_vs_Ntilde_interior_mean_L1",
        interior,
        num(sv, &["Nhat_vs_Ntilde_interior_mean_L1"]),
        rel,
        0.0,
    );
    // Plane depth z = D / (−Ñ·r + 1e-8) with D = −Ñ·(z_gt r).
    let zp: Vec<f64> = (0..w * h)
        .map(|p| {
            let (i, j) = (p % w, p / w);
            let r = [
                (i as f64 + 0.5 - b.k.cx) / b.k.fx,
                (j as f64 + 0.5 - b.k.cy) / b.k.fy,
                1.0,
            ];
            let nr: f64 = (0..3).map(|c| b.n_cam[3 * p + c] * r[c]).sum();
            -nr * b.z[p] / (-nr + 1e-8)
        })
        .collect();
    let nhat_plane = depth_normal(&zp, w, h, &b.k, None);
    let probes = b.reference["float64"]["probe_pixels_col_row"]
        .as_array()
        .unwrap()
        .clone();
    for (case, nt) in [
        ("a_gt_normal", b.n_cam.clone()),
        ("b_rotated_5deg_about_x", rot_x(&b.n_cam, 5.0)),
    ] {
        let c = &sv[case];
        let mut g_nhat = vec![0.0; w * h * 3];
        let lnc = normal_consistency(&nhat, &nt, &delta, 1.0, Some(&mut g_nhat), None);
        close(&format!("{case} L_nc"), lnc, num(c, &["L_nc"]), rel, 0.0);
        let lncp = normal_consistency(&nhat_plane, &nt, &delta, 1.0, None, None);
        close(
            &format!("{case} L_nc plane depth"),
            lncp,
            num(c, &["L_nc_with_Nhat_from_plane_depth"]),
            1e-7,
            0.0,
        );
        for (gate, gname) in [(NsGate::Above, "above"), (NsGate::Below, "below")] {
            for (pairs, suffix) in [
                (NsPairs::Interior, ""),
                (NsPairs::All, "_all_pairs_literal"),
            ] {
                let key = format!("L_ns_gate_{gname}{suffix}");
                let (v, n) =
                    normal_smoothing(&nhat, &nt, &delta, w, h, 0.01, gate, pairs, 1.0, None);
                close(&format!("{case} {key}"), v, num(c, &[&key]), rel, 0.0);
                assert_eq!(
                    n as f64,
                    num(c, &[&format!("{key}_active_pairs")]),
                    "{case} {key} active pairs"
                );
            }
        }
        // ∂L_nc/∂z.
        let mut gz = vec![0.0; w * h];
        depth_normal_backward(&b.z, w, h, &b.k, None, &g_nhat, &mut gz);
        let gr = &b.reference["float64"]["gradients"][format!("dLnc_dz_{case}")];
        let l2 = gz.iter().map(|v| v * v).sum::<f64>().sqrt();
        close(
            &format!("{case} |dLnc/dz|"),
            l2,
            num(gr, &["l2"]),
            1e-7,
            0.0,
        );
        let amax = gz.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        close(
            &format!("{case} max|dLnc/dz|"),
            amax,
            num(gr, &["abs_max"]),
            1e-6,
            1e-12,
        );
        assert_eq!(
            gz.iter().filter(|v| **v != 0.0).count() as f64,
            num(gr, &["n_nonzero_pixels"])
        );
        for p in &probes {
            let (i, j) = (
                p[0].as_u64().unwrap() as usize,
                p[1].as_u64().unwrap() as usize,
            );
            let theirs = num(gr, &["at_probe_pixels", &format!("{i},{j}")]);
            close(
                &format!("{case} dLnc/dz at ({i},{j})"),
                gz[j * w + i],
                theirs,
                1e-6,
                1e-12,
            );
        }
    }
}

/// The f32 `Image` APIs against the same reference, at its float32 tolerances.
#[test]
fn single_view_values_f32_api() {
    let b = load();
    let (w, h) = (b.w, b.h);
    let sv = &b.reference["float64"]["single_view"];
    let f32img =
        |v: &[f64], c| Image::from_vec(w, h, c, v.iter().map(|&x| x as f32).collect()).unwrap();
    let (gt, rendered) = (f32img(&b.img, 3), f32img(&b.rendered, 3));
    let guide = EdgeGuide::from_gt(&gt).unwrap();
    let li =
        gs_losses::image_loss(&rendered, &gt, Some(&guide), &ImageLossConfig::default()).unwrap();
    close("f32 L1", li.l1, num(sv, &["L1"]), 0.0, 1e-6);
    close("f32 SSIM", li.ssim, num(sv, &["SSIM"]), 0.0, 3e-6);
    close(
        "f32 edge",
        li.edge.unwrap(),
        num(sv, &["edge_L1"]),
        0.0,
        1e-6,
    );
    close("f32 L_I", li.total, num(sv, &["L_I"]), 0.0, 2e-6);
    assert!(li.grad_rendered.is_finite());
    for (case, nt) in [
        ("a_gt_normal", b.n_cam.clone()),
        ("b_rotated_5deg_about_x", rot_x(&b.n_cam, 5.0)),
    ] {
        let c = &sv[case];
        for (gate, key) in [
            (NsGate::Above, "L_ns_gate_above"),
            (NsGate::Below, "L_ns_gate_below"),
        ] {
            let cfg = NormalLossConfig {
                gate,
                ..Default::default()
            };
            let out = gs_losses::normal_losses(
                &f32img(&b.z, 1),
                &f32img(&nt, 3),
                None,
                &guide,
                &b.k,
                &cfg,
            )
            .unwrap();
            close(
                &format!("f32 {case} L_nc"),
                out.l_nc,
                num(c, &["L_nc"]),
                0.0,
                1e-6,
            );
            close(
                &format!("f32 {case} {key}"),
                out.l_ns,
                num(c, &[key]),
                1e-4,
                0.0,
            );
            assert!(out.grad_plane_depth.is_finite() && out.grad_normal.is_finite());
        }
    }
}
