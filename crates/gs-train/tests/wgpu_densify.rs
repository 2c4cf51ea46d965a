#![cfg(feature = "wgpu")]
//! Density control on the device (gs-raster's `densify_resident`, driven by gs-train's
//! `device_rule`, positions from `sample_near`) against its host twin `densify_and_prune`: the
//! same rows in the same order, bit for bit, the moments moved with their rows and zero for
//! born rows, the statistics at zero, and the same report; on the residual, budget and cap limits, the AbsGS
//! limit, the large-Gaussian prune, SH degrees 3 and 1, and a step that would leave nothing;
//! the opacity reset (`reset_opacity_resident` against `reset_opacity`); and the removal of rows
//! by a mask (`retain_resident` against `retain_rows`), statistics kept, and the records read
//! back without the SH (`read_resident_records`); a rise of the SH degree
//! (`raise_sh_degree_resident`); and the multi-view trim by views counted on the device
//! (`count_views_resident`, `retain_observed_resident`).
//!
//! Without any wgpu adapter the test prints a SKIPPED line and returns, except in CI.

use gs_core::{Adam, AdamConfig, DensifyStats, Gaussians, Param, Rng};
use gs_raster::{Backend, Rasterizer};
use gs_train::DensifyConfig;
use gs_train::densify::{DensifyReport, Growth, densify_and_prune, device_rule, sample_near};

/// A model of `n` Gaussians with varied parameters, moments and statistics: a third small
/// with large gradients (clones), a third large with large gradients (splits), the rest
/// large with large absolute gradients and radii (AbsGS splits), every seventh transparent.
fn model(n: usize, degree: u32, seed: u64) -> (Gaussians, Adam, DensifyStats) {
    let mut rng = Rng::new(seed);
    let mut g = Gaussians::with_len(0).unwrap();
    let active = gs_core::sh::coeffs_for_degree(degree);
    for i in 0..n {
        let mut sh = [[0.0; 3]; 16];
        for c in sh.iter_mut().take(active) {
            *c = [rng.normal(), rng.normal(), rng.normal()];
        }
        let scale = if i % 3 == 0 { 0.0005f32 } else { 0.05 + 0.01 * rng.uniform() as f32 };
        let rot = [1.0 + rng.normal(), rng.normal(), rng.normal(), rng.normal()];
        let opacity = if i % 7 == 6 { -8.0 } else { rng.normal() };
        g.push([rng.normal(), rng.normal(), rng.normal()], [scale.ln(), (1.3 * scale).ln(), (0.7 * scale).ln()], rot, opacity, sh);
    }
    g.sh_degree = degree;
    let mut adam = Adam::new(AdamConfig::default());
    for p in Param::ALL {
        adam.add_group(p.name(), 1e-3, n, p.row_width()).unwrap();
    }
    for group in &mut adam.groups {
        let width = group.row_width;
        for (k, (m, v)) in group.m.iter_mut().zip(group.v.iter_mut()).enumerate() {
            // Zero above the active SH degree, as training keeps them.
            let inactive = group.name == Param::ShRest.name() && k % width >= 3 * (active - 1);
            if !inactive {
                (*m, *v) = (rng.normal(), rng.uniform() as f32);
            }
        }
    }
    let mut st = DensifyStats::new(n);
    for i in 0..n {
        st.visible_count[i] = 1 + (i % 4) as u32;
        let v = st.visible_count[i] as f32;
        // Distinct scores, well clear of the thresholds.
        let strength = v * (1.5 + i as f32 * 1e-3);
        match i % 3 {
            0 | 1 => st.grad_sum[i] = strength * 2e-4,
            _ => st.abs_grad_sum[i] = strength * 8e-4,
        }
        st.max_radius[i] = if i % 5 == 0 { 40.0 } else { 25.0 };
    }
    (g, adam, st)
}

/// The device's densification of the model next to the host's, compared row by row.
fn compare(wgpu: &mut Rasterizer, n: usize, degree: u32, cfg: &DensifyConfig, prune_big: bool, growth: Growth) -> DensifyReport {
    let (g, adam, st) = model(n, degree, n as u64 + degree as u64);
    let (mut host_g, mut host_adam, mut host_st) = (g.clone(), adam.clone(), st.clone());
    let host = densify_and_prune(&mut host_g, &mut host_adam, &mut host_st, cfg, 2.0, prune_big, growth, &mut Rng::new(9)).unwrap();
    wgpu.make_resident(&g, &adam, &st).unwrap();
    let rule = device_rule(cfg, 2.0, prune_big, growth.room(n));
    let mut rng = Rng::new(9);
    let counts = wgpu.densify_resident(&g, &rule, &mut |p| sample_near(p, &mut rng)).unwrap().expect("the device takes the step");
    assert_eq!((counts.cloned, counts.split, counts.removed - counts.split, counts.len), (host.cloned, host.split, host.pruned, host_g.len()));
    assert_eq!(growth.limit(counts.candidates, rule.room), host.limit);
    // Read back into placeholders of the new size, as the trainer keeps them.
    let mut dev_g = Gaussians::with_len(counts.len).unwrap();
    dev_g.sh_degree = degree;
    let mut dev_adam = adam.clone();
    for group in &mut dev_adam.groups {
        group.m = vec![0.0; counts.len * group.row_width];
        group.v = vec![0.0; counts.len * group.row_width];
    }
    let mut dev_st = DensifyStats::new(counts.len);
    dev_st.grad_sum.fill(7.0);
    wgpu.read_resident(&mut dev_g, Some((&mut dev_adam, &mut dev_st))).unwrap();
    assert_eq!(dev_st, DensifyStats::new(counts.len), "the statistics start again at zero");
    assert_eq!(dev_g, host_g, "every parameter bit for bit");
    assert_eq!(dev_adam, host_adam, "the moments move with their rows, zero for born rows");
    wgpu.release_resident();
    host
}

fn wgpu_rasterizer() -> Option<Rasterizer> {
    match Rasterizer::new(Backend::Wgpu) {
        Ok(r) => Some(r),
        Err(e) => {
            gs_testdata::skip_or_fail!(&format!("no wgpu adapter: {e}"), "install mesa-vulkan-drivers for lavapipe");
            None
        }
    }
}

#[test]
fn the_device_densifies_as_the_host_does() {
    let Some(mut wgpu) = wgpu_rasterizer() else { return };
    let cfg = DensifyConfig::default();
    let open = Growth { target: usize::MAX, cap: 1_000_000 };
    // Every candidate grows; the transparent seventh are pruned.
    let all = compare(&mut wgpu, 300, 3, &cfg, false, open);
    assert!(all.cloned > 50 && all.split > 100 && all.pruned > 20, "{all:?}");
    assert_eq!(all.limit, gs_train::GrowthLimit::Residual);
    // The budget takes the best scores (the highest indices here), then the cap.
    let budget = compare(&mut wgpu, 300, 3, &cfg, false, Growth { target: 340, cap: 1_000_000 });
    assert_eq!((budget.cloned + budget.split, budget.limit), (40, gs_train::GrowthLimit::Budget));
    let cap = compare(&mut wgpu, 300, 1, &cfg, false, Growth { target: usize::MAX, cap: 310 });
    assert!(cap.capped && cap.cloned + cap.split == 10);
    // The AbsGS limit and the large-Gaussian prune (radii of 40 over 20 pixels).
    let few = DensifyConfig { max_abs_splits: 7, ..cfg.clone() };
    let limited = compare(&mut wgpu, 300, 1, &few, true, open);
    assert!(limited.split < all.split && limited.pruned > all.pruned, "{limited:?} against {all:?}");
    // More than one chunk of work per kernel and a scan of several levels.
    compare(&mut wgpu, 5000, 3, &cfg, true, Growth { target: 5600, cap: 1_000_000 });
}

#[test]
fn a_step_that_would_leave_nothing_is_declined() {
    let Some(mut wgpu) = wgpu_rasterizer() else { return };
    let (g, adam, st) = model(20, 0, 1);
    // Everything below the minimum opacity: the host keeps the most opaque one, the device declines.
    let cfg = DensifyConfig { min_opacity: 0.9999, ..DensifyConfig::default() };
    wgpu.make_resident(&g, &adam, &st).unwrap();
    let rule = device_rule(&cfg, 2.0, false, 0);
    let mut rng = Rng::new(1);
    assert_eq!(wgpu.densify_resident(&g, &rule, &mut |p| sample_near(p, &mut rng)).unwrap(), None);
    let (mut back, mut back_adam, mut back_st) = (g.clone(), adam.clone(), DensifyStats::new(20));
    wgpu.read_resident(&mut back, Some((&mut back_adam, &mut back_st))).unwrap();
    assert_eq!((&back, &back_adam, &back_st), (&g, &adam, &st), "the resident model is unchanged");
    // The CPU backend has nothing resident to densify.
    let mut cpu = Rasterizer::new(Backend::Cpu).unwrap();
    assert!(cpu.densify_resident(&g, &rule, &mut |p| sample_near(p, &mut rng)).is_err());
}

#[test]
fn the_device_resets_opacities_as_the_host_does() {
    let Some(mut wgpu) = wgpu_rasterizer() else { return };
    let (mut g, adam, st) = model(500, 2, 3);
    // Some opacities just below and above the reset level.
    for (i, o) in g.opacity_logits.iter_mut().enumerate().step_by(5) {
        *o = gs_core::gaussians::inverse_sigmoid(if i % 2 == 0 { 0.0099 } else { 0.0101 });
    }
    let (mut host_g, mut host_adam) = (g.clone(), adam.clone());
    gs_train::densify::reset_opacity(&mut host_g, &mut host_adam).unwrap();
    wgpu.make_resident(&g, &adam, &st).unwrap();
    let level = gs_train::densify::RESET_OPACITY;
    wgpu.reset_opacity_resident(&g, level, gs_core::gaussians::inverse_sigmoid(level)).unwrap();
    let (mut dev_g, mut dev_adam, mut dev_st) = (g.clone(), adam.clone(), st.clone());
    wgpu.read_resident(&mut dev_g, Some((&mut dev_adam, &mut dev_st))).unwrap();
    assert_eq!(dev_g, host_g, "the parameters bit for bit");
    assert_eq!(dev_adam, host_adam, "the opacity moments at zero, the others as they were");
    assert_eq!(dev_st, st, "the statistics untouched");
    assert!(host_g.opacity_logits != g.opacity_logits, "the reset changed opacities");
}

/// Removing rows on the device (`retain_resident`) against the host's `retain_rows` and the
/// statistics' `retain`: the survivors' parameters, moments and statistics bit for bit.
#[test]
fn the_device_removes_rows_as_the_host_does() {
    let Some(mut wgpu) = wgpu_rasterizer() else { return };
    for (n, degree) in [(5000, 3), (300, 0)] {
        let (g, adam, st) = model(n, degree, 11);
        let mut rng = Rng::new(5);
        let keep: Vec<bool> = (0..n).map(|_| rng.uniform() < 0.6).collect();
        let (mut host_g, mut host_adam, mut host_st) = (g.clone(), adam.clone(), st.clone());
        let removed = gs_train::densify::retain_rows(&mut host_g, &mut host_adam, &mut keep.clone()).unwrap();
        host_st.retain(&keep);
        wgpu.make_resident(&g, &adam, &st).unwrap();
        let kept = wgpu.retain_resident(&g, &keep).unwrap().expect("the device takes the removal");
        assert_eq!(kept, n - removed);
        let (mut dev_g, mut dev_adam, mut dev_st) = (Gaussians::with_len(kept).unwrap(), host_adam.clone(), DensifyStats::new(kept));
        dev_g.sh_degree = degree;
        for group in &mut dev_adam.groups {
            group.m.fill(0.0);
            group.v.fill(0.0);
        }
        wgpu.read_resident(&mut dev_g, Some((&mut dev_adam, &mut dev_st))).unwrap();
        assert_eq!(dev_g, host_g, "every parameter bit for bit");
        assert_eq!(dev_adam, host_adam, "the moments with their rows");
        assert_eq!(dev_st, host_st, "the statistics with their rows");
        // The records alone: the geometry and opacities, the SH left as they were.
        let mut records = Gaussians::with_len(kept).unwrap();
        records.sh_degree = degree;
        wgpu.read_resident_records(&mut records).unwrap();
        let fields = |g: &Gaussians| (g.means.clone(), g.log_scales.clone(), g.rotations.clone(), g.opacity_logits.clone());
        assert_eq!(fields(&records), fields(&host_g));
        assert!(records.sh.iter().all(|c| *c == [[0.0; 3]; 16]), "the SH are not read");
        // Keeping every row changes nothing; a mask of another length or that keeps nothing is refused.
        assert_eq!(wgpu.retain_resident(&dev_g, &vec![true; kept]).unwrap(), Some(kept));
        assert!(wgpu.retain_resident(&dev_g, &vec![true; kept + 1]).is_err());
        assert!(wgpu.retain_resident(&dev_g, &vec![false; kept]).is_err());
        let mut again = dev_g.clone();
        wgpu.read_resident(&mut again, None).unwrap();
        assert_eq!(again, dev_g, "the refused masks left the model as it was");
        wgpu.release_resident();
    }
    let mut cpu = Rasterizer::new(Backend::Cpu).unwrap();
    let (g, _, _) = model(10, 0, 1);
    assert!(cpu.retain_resident(&g, &[true; 10]).is_err(), "the CPU backend has nothing resident");
}

/// A rise of the SH degree on the device (`raise_sh_degree_resident`): the coefficients and
/// moments kept, the new bands' zero, as the host's model at the new degree.
#[test]
fn the_device_raises_the_sh_degree_as_the_host_does() {
    let Some(mut wgpu) = wgpu_rasterizer() else { return };
    for (from, to) in [(0, 1), (1, 3)] {
        let (g, adam, st) = model(700, from, 13);
        wgpu.make_resident(&g, &adam, &st).unwrap();
        assert!(wgpu.raise_sh_degree_resident(&g, to).unwrap());
        let mut host_g = g.clone();
        host_g.sh_degree = to;
        let (mut dev_g, mut dev_adam, mut dev_st) = (host_g.clone(), adam.clone(), st.clone());
        dev_g.sh.iter_mut().for_each(|c| *c = [[9.0; 3]; 16]);
        for group in &mut dev_adam.groups {
            group.m.fill(9.0);
        }
        wgpu.read_resident(&mut dev_g, Some((&mut dev_adam, &mut dev_st))).unwrap();
        let active = gs_core::sh::coeffs_for_degree(to);
        // The device holds the active bands' moments alone: those above were not read.
        let rest = dev_adam.groups.iter_mut().find(|g| g.name == Param::ShRest.name()).unwrap();
        let width = rest.row_width;
        rest.m.chunks_mut(width).for_each(|row| row[3 * (active - 1)..].fill(0.0));
        let shown = |g: &Gaussians| g.sh.iter().map(|c| c[..active].to_vec()).collect::<Vec<_>>();
        assert_eq!(shown(&dev_g), shown(&host_g), "the coefficients kept, the new bands zero ({from} to {to})");
        assert_eq!((&dev_g.means, &dev_g.opacity_logits), (&host_g.means, &host_g.opacity_logits));
        assert!(dev_adam == adam && dev_st == st, "the moments kept, the new bands' zero ({from} to {to})");
        // Not a rise: refused, the model as it was.
        assert!(wgpu.raise_sh_degree_resident(&host_g, to).is_err());
        wgpu.release_resident();
    }
}

/// The multi-view trim on the device (`count_views_resident`, `retain_observed_resident`)
/// against the host's: the view counts of each view's render read back (`views_observed`'s
/// sum), and the rows a mask of `observed_enough` keeps, bit for bit with their moments and
/// statistics; counts are used once and are of one model; a trim that would keep nothing
/// changes nothing and says so (the counts stay for the host's rule).
#[test]
fn the_device_trims_as_the_host_does() {
    use gs_core::glam::DVec3;
    use gs_core::{Camera, Intrinsics};
    use gs_raster::{RasterConfig, RenderRequest, TrimOnDevice};
    let Some(mut wgpu) = wgpu_rasterizer() else { return };
    let (g, adam, st) = model(3000, 1, 21);
    let k = Intrinsics::new(60.0, 60.0, 40.0, 30.0);
    let cams: Vec<Camera> = (0..6)
        .map(|i| {
            let a = i as f64;
            Camera::look_at(80, 60, k, DVec3::new(4.0 * a.cos(), 4.0 * a.sin(), 1.5), DVec3::ZERO, DVec3::Z).unwrap()
        })
        .collect();
    let refs: Vec<&Camera> = cams.iter().collect();
    let config = RasterConfig::default();
    let req = RenderRequest { color: false, alpha: false, observed: true, ..RenderRequest::default() };
    let mut host_counts = vec![0u32; g.len()];
    for c in &cams {
        let out = wgpu.render(&g, c, &req, &config).unwrap();
        host_counts.iter_mut().zip(out.observed.as_ref().unwrap()).for_each(|(h, &o)| *h += (o > 0) as u32);
    }
    let min = 3;
    let mut keep = gs_train::densify::observed_enough(&host_counts, min);
    let (mut host_g, mut host_adam, mut host_st) = (g.clone(), adam.clone(), st.clone());
    let removed = gs_train::densify::retain_rows(&mut host_g, &mut host_adam, &mut keep).unwrap();
    host_st.retain(&keep);
    assert!(removed > 0 && removed < g.len(), "a trim that removes some: {removed} of {}", g.len());

    wgpu.make_resident(&g, &adam, &st).unwrap();
    assert!(wgpu.retain_observed_resident(&g, min).is_err(), "no counts yet");
    wgpu.count_views_resident(&g, &refs, &config).unwrap();
    assert_eq!(wgpu.read_view_counts().unwrap(), host_counts, "the views counted on the device");
    let kept = g.len() - removed;
    assert_eq!(wgpu.retain_observed_resident(&g, min).unwrap(), Some(TrimOnDevice::Kept(kept)));
    let (mut dev_g, mut dev_adam, mut dev_st) = (Gaussians::with_len(kept).unwrap(), host_adam.clone(), DensifyStats::new(kept));
    dev_g.sh_degree = 1;
    wgpu.read_resident(&mut dev_g, Some((&mut dev_adam, &mut dev_st))).unwrap();
    assert_eq!(dev_g, host_g, "every parameter bit for bit");
    assert_eq!(dev_adam, host_adam, "the moments with their rows");
    assert_eq!(dev_st, host_st, "the statistics with their rows");
    assert!(wgpu.retain_observed_resident(&dev_g, min).is_err(), "the counts were of the model before the trim");
    // A trim that would keep nothing changes nothing; the counts stay for the host's rule.
    wgpu.count_views_resident(&dev_g, &refs, &config).unwrap();
    assert_eq!(wgpu.retain_observed_resident(&dev_g, 1000).unwrap(), Some(TrimOnDevice::NoneKept));
    assert_eq!(wgpu.read_view_counts().unwrap().len(), kept);
    let mut again = dev_g.clone();
    wgpu.read_resident(&mut again, None).unwrap();
    assert_eq!(again, dev_g, "the model as it was");
    wgpu.release_resident();
    let mut cpu = Rasterizer::new(Backend::Cpu).unwrap();
    assert!(cpu.count_views_resident(&g, &refs, &config).is_err(), "the CPU backend has nothing resident");
}

/// The capture path's floater rule on the device (`mark_capsules_resident`,
/// `retain_outside_resident`) against the host's `CapturePath::contains` and `retain_rows`:
/// a ring of 16 cameras around a model, with rows placed within rounding of a capsule's side
/// and of its cameras' image planes, which f32 cannot settle: they come back, the host tests
/// them, and the rows kept are the host's, bit for bit with their moments and statistics.
/// Marks are used once and are of one model; a rule that would keep nothing changes nothing.
#[test]
fn the_device_removes_what_lies_in_front_of_the_path_as_the_host_does() {
    use gs_core::glam::DVec3;
    use gs_core::{Camera, Capsule, Intrinsics};
    use gs_raster::TrimOnDevice;
    use gs_train::capture_path::CapturePath;
    let Some(mut wgpu) = wgpu_rasterizer() else { return };
    let cams: Vec<Camera> = (0..16)
        .map(|k| {
            let a = k as f64 / 16.0 * std::f64::consts::TAU;
            let c = DVec3::new(2.5 * a.cos(), 2.5 * a.sin(), 0.0);
            Camera::look_at(64, 48, Intrinsics::new(60.0, 60.0, 32.0, 24.0), c, DVec3::ZERO, DVec3::Z).unwrap()
        })
        .collect();
    let refs: Vec<&Camera> = cams.iter().collect();
    let path = CapturePath::new(&refs, 1.0, &[]);
    let (mut g, mut adam, mut st) = model(3000, 1, 31);
    // Rows on the boundaries, each within 1e-6 of the capsule's size from it: a link's side
    // (half of them just inside), and a camera's image plane.
    let mut edges = Vec::new();
    for (k, c) in path.capsules().iter().enumerate().filter(|(_, c)| c.a != c.b).take(24) {
        let (mid, side) = ((c.a + c.b) / 2.0, (c.b - c.a).cross(DVec3::Z).normalize());
        let side = if side.dot(c.fa) > 0.0 { side } else { -side };
        let at = mid + side * c.radius * (1.0 + if k % 2 == 0 { 1e-6 } else { -1e-6 });
        edges.push(at);
    }
    for c in path.capsules().iter().filter(|c| c.a == c.b).take(8) {
        edges.push(c.a + c.fa.cross(DVec3::Z).normalize() * 0.3 * c.radius + c.fa * 1e-7);
    }
    let first_edge = g.len();
    let mut sh = [[0.0; 3]; 16];
    sh[..4].fill([0.1; 3]); // degree 1: the inactive coefficients zero, as training keeps them
    for p in &edges {
        g.push(p.as_vec3().to_array(), [-3.0; 3], [1.0, 0.0, 0.0, 0.0], 0.5, sh);
    }
    let n = g.len();
    adam.extend_rows(edges.len());
    st.visible_count.resize(n, 2);
    st.grad_sum.resize(n, 1e-4);
    st.abs_grad_sum.resize(n, 2e-4);
    st.max_radius.resize(n, 3.0);
    let inside_host = |g: &Gaussians, i: usize| path.contains(DVec3::from(g.means[i].map(f64::from)));
    let keep: Vec<bool> = (0..n).map(|i| !inside_host(&g, i)).collect();
    let (mut host_g, mut host_adam, mut host_st) = (g.clone(), adam.clone(), st.clone());
    let removed = gs_train::densify::retain_rows(&mut host_g, &mut host_adam, &mut keep.clone()).unwrap();
    host_st.retain(&keep);
    assert!(removed > 100 && removed < n, "the path holds some of the model: {removed} of {n}");

    wgpu.make_resident(&g, &adam, &st).unwrap();
    assert!(wgpu.retain_outside_resident(&g, &[]).is_err(), "no marks yet");
    let unsure = wgpu.mark_capsules_resident(&g, path.capsules()).unwrap().expect("the device takes the marks");
    let rows: Vec<usize> = unsure.iter().map(|(i, _)| *i).collect();
    // A boundary row another capsule surely holds is settled there; the others come back.
    assert!(rows.iter().filter(|&&i| i >= first_edge).count() >= 4, "rows on a boundary are left to the host: {rows:?}");
    assert!(unsure.iter().all(|(i, m)| g.means[*i] == *m), "with its mean");
    let inside: Vec<usize> = rows.iter().copied().filter(|&i| inside_host(&g, i)).collect();
    assert!(!inside.is_empty() && inside.len() < rows.len(), "boundary rows on both sides: {} of {}", inside.len(), rows.len());
    assert!(wgpu.retain_outside_resident(&g, &[n]).is_err(), "a row beyond the model");
    let unsure = wgpu.mark_capsules_resident(&g, path.capsules()).unwrap().expect("marked again");
    assert_eq!(unsure.len(), rows.len());
    let kept = n - removed;
    assert_eq!(wgpu.retain_outside_resident(&g, &inside).unwrap(), Some(TrimOnDevice::Kept(kept)));
    let (mut dev_g, mut dev_adam, mut dev_st) = (Gaussians::with_len(kept).unwrap(), host_adam.clone(), DensifyStats::new(kept));
    dev_g.sh_degree = 1;
    wgpu.read_resident(&mut dev_g, Some((&mut dev_adam, &mut dev_st))).unwrap();
    assert!(dev_g == host_g, "every parameter bit for bit");
    assert!(dev_adam == host_adam, "the moments with their rows");
    assert!(dev_st == host_st, "the statistics with their rows");
    assert!(wgpu.retain_outside_resident(&dev_g, &[]).is_err(), "the marks were of the model before");
    // Nothing left in front of the path (the unsure rows left are outside): everything stays.
    let unsure = wgpu.mark_capsules_resident(&dev_g, path.capsules()).unwrap().unwrap();
    assert!(!unsure.is_empty() && unsure.iter().all(|&(i, _)| !inside_host(&dev_g, i)));
    assert_eq!(wgpu.retain_outside_resident(&dev_g, &[]).unwrap(), Some(TrimOnDevice::Kept(kept)));
    // A capsule holding everything: nothing changes, and the caller is told.
    let all = Capsule { a: DVec3::new(0.0, 0.0, -50.0), b: DVec3::new(0.0, 0.0, -50.0), radius: 100.0, fa: DVec3::Z, fb: DVec3::Z };
    assert!(wgpu.mark_capsules_resident(&dev_g, &[all]).unwrap().unwrap().is_empty());
    assert_eq!(wgpu.retain_outside_resident(&dev_g, &[]).unwrap(), Some(TrimOnDevice::NoneKept));
    let mut again = dev_g.clone();
    wgpu.read_resident(&mut again, None).unwrap();
    assert_eq!(again, dev_g, "the model as it was");
    wgpu.release_resident();
    let mut cpu = Rasterizer::new(Backend::Cpu).unwrap();
    assert!(cpu.mark_capsules_resident(&g, path.capsules()).is_err(), "the CPU backend has nothing resident");
}
