//! Mip-Splatting's 3D smoothing filter (docs/method.md §3D smoothing): every Gaussian is
//! convolved with an isotropic Gaussian of variance s² = k·(z/f)², where z/f is the finest
//! world-space sampling interval that any training view has of its centre (z its depth, f the
//! focal length; views whose frustum, widened by [`FRUSTUM_MARGIN`], holds the centre in front
//! of the near plane). So no Gaussian is thinner than the training views could have seen, which
//! a screen-space filter cannot tell apart from a surface that is fine.
//!
//! The filter is rotation-free: Σ' = Σ + s²·I has the scales √(σᵢ² + s²) on the same axes, and
//! the opacity is multiplied by √(det Σ / det Σ') so that the Gaussian's integral is kept. It
//! therefore wraps either rasterizer on the host: [`Smoothing::apply`] writes the filtered
//! log-scales and opacity logits into the Gaussians (the model at rest, the one rendered,
//! evaluated, meshed and exported), keeping the optimised (raw) values aside;
//! [`Smoothing::chain`] carries the rasterizer's gradients back to the raw values and
//! [`Smoothing::revert`] puts them back for Adam and density control. The variances are
//! recomputed every [`RECOMPUTE_EVERY`] iterations and whenever density control changes the
//! rows, and are part of the checkpoint, so a resumed run is bit-identical.

use crate::error::{Result, TrainError};
use crate::trainer::TrainState;
use gs_core::{Camera, Gaussians};
use gs_raster::GaussianGradients;
use rayon::prelude::*;

/// Iterations between two computations of the variances (Mip-Splatting's 100).
pub const RECOMPUTE_EVERY: u64 = 100;

/// The largest accepted `smoothing_3d` k: at 16 the filter's standard deviation is four
/// sampling intervals, past any use.
pub const MAX_K: f32 = 16.0;

/// A centre counts as seen by a view when it projects within this multiple of the image,
/// measured from the image's centre (Mip-Splatting's 15 % margin).
pub const FRUSTUM_MARGIN: f64 = 1.15;

/// The filter's state in a run: the variances, the raw parameters while the Gaussians hold the
/// filtered ones, and which of the two the Gaussians hold.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Smoothing {
    /// s² per Gaussian (world units²), each finite and non-negative.
    variances: Vec<f32>,
    /// While `applied`: the raw log-scales; otherwise scratch.
    spare_log_scales: Vec<[f32; 3]>,
    /// While `applied`: the raw opacity logits; otherwise scratch.
    spare_opacity_logits: Vec<f32>,
    /// While `applied`: each Gaussian's partial derivatives through the filter.
    partials: Vec<Partials<f32>>,
    /// Whether the Gaussians hold the filtered values.
    applied: bool,
}

impl Smoothing {
    /// A filter with `variances` (one per Gaussian), not yet applied. Refuses a variance that
    /// is not a finite, non-negative number, so that [`Smoothing::apply`] need not scan them.
    pub fn new(variances: Vec<f32>) -> Result<Self> {
        if let Some(v) = variances.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
            return Err(TrainError::InvalidConfig(format!("3D smoothing: variance {v} is not a finite, non-negative number")));
        }
        Ok(Self { variances, ..Self::default() })
    }

    /// s² per Gaussian (world units²).
    pub fn variances(&self) -> &[f32] {
        &self.variances
    }

    /// Whether the Gaussians hold the filtered values.
    pub fn applied(&self) -> bool {
        self.applied
    }

    /// Writes the filtered log-scales and opacity logits into `g`, keeping the raw ones aside
    /// and the partial derivatives for [`Smoothing::chain`]. Does nothing when already applied.
    pub fn apply(&mut self, g: &mut Gaussians) -> Result<()> {
        if self.applied {
            return Ok(());
        }
        let n = g.len();
        self.check_rows(n)?;
        std::mem::swap(&mut g.log_scales, &mut self.spare_log_scales);
        std::mem::swap(&mut g.opacity_logits, &mut self.spare_opacity_logits);
        // One pass writes the filtered values in place and keeps only the partial derivatives.
        g.log_scales.resize(n, [0.0; 3]);
        g.opacity_logits.resize(n, 0.0);
        self.partials.resize(n, Partials::default());
        let raw = self.spare_log_scales.par_iter().zip(&self.spare_opacity_logits).zip(&self.variances);
        let out = g.log_scales.par_iter_mut().zip(g.opacity_logits.par_iter_mut()).zip(self.partials.par_iter_mut());
        out.zip(raw).for_each(|(((l_out, o_out), p_out), ((l, &o), &s2))| {
            let f = filter_one(*l, o, s2);
            (*l_out, *o_out, *p_out) = (f.log_scales, f.logit, f.partials);
        });
        self.applied = true;
        Ok(())
    }

    /// Puts the raw log-scales and opacity logits back into `g`. Does nothing when not applied.
    pub fn revert(&mut self, g: &mut Gaussians) {
        if self.applied {
            std::mem::swap(&mut g.log_scales, &mut self.spare_log_scales);
            std::mem::swap(&mut g.opacity_logits, &mut self.spare_opacity_logits);
            self.applied = false;
        }
    }

    /// Turns gradients with respect to the filtered log-scales and opacity logits into
    /// gradients with respect to the raw ones (the other parameters pass through unchanged).
    /// Needs the filter applied.
    pub fn chain(&self, grads: &mut GaussianGradients) -> Result<()> {
        if !self.applied || grads.log_scales.len() != self.partials.len() || grads.opacity_logits.len() != self.partials.len() {
            return Err(TrainError::InvalidConfig("3D smoothing: gradients do not match the filtered Gaussians".into()));
        }
        let rows = grads.log_scales.par_iter_mut().zip(grads.opacity_logits.par_iter_mut()).zip(&self.partials);
        rows.for_each(|((gl, go), p)| {
            let g_logit = *go;
            *gl = std::array::from_fn(|i| gl[i] * p.scale_scale[i] + g_logit * p.logit_scale[i]);
            *go = g_logit * p.logit_logit;
        });
        Ok(())
    }

    /// The raw log-scales and opacity logits, whichever the Gaussians hold now.
    pub fn raw<'a>(&'a self, g: &'a Gaussians) -> (&'a [[f32; 3]], &'a [f32]) {
        match self.applied {
            true => (&self.spare_log_scales, &self.spare_opacity_logits),
            false => (&g.log_scales, &g.opacity_logits),
        }
    }

    /// Refuses variances that do not match `n` Gaussians (their values were checked on entry).
    fn check_rows(&self, n: usize) -> Result<()> {
        if self.variances.len() != n {
            return Err(TrainError::InvalidConfig(format!("3D smoothing: {} variances for {n} Gaussians", self.variances.len())));
        }
        Ok(())
    }
}

/// Brings `state`'s filter in line with the run's `k` (`smoothing_3d`): off drops it, putting
/// the raw values back; on computes the variances over `cameras` when `recompute`, when there
/// are none or when density control changed the rows, and leaves the filter applied.
pub(crate) fn settle(state: &mut TrainState, cameras: &[&Camera], near: f64, k: f32, recompute: bool) -> Result<()> {
    if k <= 0.0 {
        if let Some(mut s) = state.smoothing.take() {
            s.revert(&mut state.gaussians);
        }
        return Ok(());
    }
    let s = state.smoothing.get_or_insert_with(Smoothing::default);
    if recompute || s.variances.len() != state.gaussians.len() {
        s.revert(&mut state.gaussians);
        s.variances = variances(&state.gaussians, cameras, near, f64::from(k));
    }
    s.apply(&mut state.gaussians)
}

/// s² = `k`·(z/f)² for every centre of `g` over `cameras`: z/f is the smallest over the views
/// that see the centre (depth z beyond `near`, projection within [`FRUSTUM_MARGIN`]); a centre
/// that no view sees takes the largest z/f of those seen (Mip-Splatting's rule), or 0 when no
/// centre is seen at all.
pub fn variances(g: &Gaussians, cameras: &[&Camera], near: f64, k: f64) -> Vec<f32> {
    let interval: Vec<Option<f64>> = g.means.par_iter().map(|m| finest_interval(m, cameras, near)).collect();
    let fallback = interval.iter().flatten().copied().fold(0.0f64, f64::max);
    interval.iter().map(|d| (k * d.unwrap_or(fallback).powi(2)) as f32).collect()
}

/// The smallest z/f of `mean` over the views that see it.
fn finest_interval(mean: &[f32; 3], cameras: &[&Camera], near: f64) -> Option<f64> {
    let p = gs_core::glam::DVec3::from(mean.map(f64::from));
    let mut best: Option<f64> = None;
    for cam in cameras {
        let c = cam.world_to_camera(p);
        if c.z <= near {
            continue;
        }
        let k = &cam.intrinsics;
        let (u, v) = (k.fx * c.x / c.z + k.cx, k.fy * c.y / c.z + k.cy);
        let (w, h) = (f64::from(cam.width), f64::from(cam.height));
        let inside = |x: f64, size: f64| (x - 0.5 * size).abs() <= 0.5 * size * FRUSTUM_MARGIN;
        if inside(u, w) && inside(v, h) {
            let d = c.z / k.fx.max(k.fy);
            best = Some(best.map_or(d, |b: f64| b.min(d)));
        }
    }
    best
}

/// The arithmetic of the filter, in f32 for training and f64 for the finite-difference tests.
pub trait Real:
    Copy
    + PartialOrd
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
    + std::ops::Neg<Output = Self>
{
    /// The number `x`.
    fn of(x: f32) -> Self;
    /// eˣ.
    fn exp(self) -> Self;
    /// ln x.
    fn ln(self) -> Self;
    /// ln(1 + x).
    fn ln_1p(self) -> Self;
    /// eˣ − 1.
    fn exp_m1(self) -> Self;
}

macro_rules! real {
    ($t:ty) => {
        impl Real for $t {
            fn of(x: f32) -> Self {
                x as $t
            }
            fn exp(self) -> Self {
                <$t>::exp(self)
            }
            fn ln(self) -> Self {
                <$t>::ln(self)
            }
            fn ln_1p(self) -> Self {
                <$t>::ln_1p(self)
            }
            fn exp_m1(self) -> Self {
                <$t>::exp_m1(self)
            }
        }
    };
}
real!(f32);
real!(f64);

/// One Gaussian through the filter: its filtered log-scales and logit, and the partial
/// derivatives that carry gradients back.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Filtered<R> {
    /// ½·ln(σᵢ² + s²).
    pub log_scales: [R; 3],
    /// logit(σ(o)·c), c = Πᵢ √(σᵢ² / (σᵢ² + s²)).
    pub logit: R,
    /// The partial derivatives of the filtered values with respect to the raw ones.
    pub partials: Partials<R>,
}

/// The partial derivatives of one Gaussian's filtered log-scales l' and logit o' with respect
/// to its raw l and o (what [`Smoothing::chain`] keeps between the render and the backward).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Partials<R> {
    /// ∂l'ᵢ/∂lᵢ = σᵢ²/(σᵢ² + s²).
    pub scale_scale: [R; 3],
    /// ∂o'/∂lᵢ = s²/((σᵢ² + s²)(1 − σ(o)·c)).
    pub logit_scale: [R; 3],
    /// ∂o'/∂o = (1 − σ(o))/(1 − σ(o)·c), in (0, 1].
    pub logit_logit: R,
}

/// ln(1 + eˣ) without overflow.
fn softplus<R: Real>(x: R) -> R {
    let zero = R::of(0.0);
    let (pos, neg_abs) = if x > zero { (x, -x) } else { (zero, x) };
    pos + neg_abs.exp().ln_1p()
}

/// Filters one Gaussian (log-scales `l`, logit `o`) by the variance `s2` (docs/method.md §3D
/// smoothing). logit(p·c) = ln p + ln c − ln(1 − p·c) with 1 − p·c = (1 − c) + c·σ(−o), so
/// nothing cancels; where 1 − p·c is 0 (p = c = 1) the derivatives take their limits.
pub fn filter_one<R: Real>(l: [R; 3], o: R, s2: R) -> Filtered<R> {
    let (zero, one, half, two) = (R::of(0.0), R::of(1.0), R::of(0.5), R::of(2.0));
    let v = l.map(|x| (two * x).exp());
    let w = v.map(|x| x + s2);
    let ln_w = w.map(|x| x.ln());
    let ln_c = (l[0] - half * ln_w[0]) + (l[1] - half * ln_w[1]) + (l[2] - half * ln_w[2]);
    let sp = softplus(o); // ln(1 + eᵒ); ln p = −softplus(−o) = o − sp
    let q = (-sp).exp(); // σ(−o) = 1 − p
    let c_minus_one = ln_c.exp_m1();
    let rest = -c_minus_one + (one + c_minus_one) * q; // 1 − p·c
    let inv = if rest > zero { one / rest } else { zero };
    let share = |i: usize| if w[i] > zero { one / w[i] } else { zero };
    Filtered {
        log_scales: ln_w.map(|x| half * x),
        logit: (o - sp) + ln_c - rest.ln(),
        partials: Partials {
            scale_scale: std::array::from_fn(|i| v[i] * share(i)),
            logit_scale: std::array::from_fn(|i| s2 * share(i) * inv),
            logit_logit: if rest > zero { q * inv } else { one },
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// L = a·l' + b·o' for fixed weights, in f64.
    fn loss(ls: [f64; 3], o: f64, s2: f64, a: [f64; 3], b: f64) -> f64 {
        let f = filter_one(ls, o, s2);
        (0..3).map(|i| a[i] * f.log_scales[i]).sum::<f64>() + b * f.logit
    }

    /// ∂L/∂(l, o) of that loss through the partials.
    fn chain_rule(ls: [f64; 3], o: f64, s2: f64, a: [f64; 3], b: f64) -> ([f64; 3], f64) {
        let p = filter_one(ls, o, s2).partials;
        (std::array::from_fn(|i| a[i] * p.scale_scale[i] + b * p.logit_scale[i]), b * p.logit_logit)
    }

    fn filtered(ls: [f64; 3], o: f64, s2: f64) -> ([f64; 3], f64) {
        let f = filter_one(ls, o, s2);
        (f.log_scales, f.logit)
    }

    fn sigmoid64(x: f64) -> f64 {
        1.0 / (1.0 + (-x).exp())
    }

    #[test]
    fn the_chain_rule_matches_finite_differences_at_the_extremes() {
        let (a, b) = ([0.7, -1.3, 0.4], -0.9);
        let cases = [
            ([-3.0, -2.5, -6.0], 0.3, 0.01),
            ([-8.0, -8.5, -12.0], 4.0, 1e-4),
            ([1.0, 0.5, -1.0], -12.0, 2.0),
            ([-5.0, -5.0, -5.0], 12.0, 1e-6),
            ([-2.0, -3.0, -4.0], 1.5, 0.0),
            ([-4.0, -4.0, -9.0], 30.0, 1e-5),
        ];
        for (ls, o, s2) in cases {
            let (gl, go) = chain_rule(ls, o, s2, a, b);
            let h = 1e-6;
            for i in 0..3 {
                let (mut p, mut m) = (ls, ls);
                p[i] += h;
                m[i] -= h;
                let fd = (loss(p, o, s2, a, b) - loss(m, o, s2, a, b)) / (2.0 * h);
                assert!((fd - gl[i]).abs() <= 1e-6 * (1.0 + fd.abs()), "∂/∂l{i} at {ls:?} {o} {s2}: {} vs {fd}", gl[i]);
            }
            let fd = (loss(ls, o + h, s2, a, b) - loss(ls, o - h, s2, a, b)) / (2.0 * h);
            assert!((fd - go).abs() <= 1e-6 * (1.0 + fd.abs()), "∂/∂o at {ls:?} {o} {s2}: {go} vs {fd}");
        }
    }

    #[test]
    fn the_filter_keeps_the_integral_and_widens_every_axis() {
        let (ls, o, s2) = ([-4.0, -3.0, -7.0], 2.0, 1e-4);
        let (fl, fo) = filtered(ls, o, s2);
        // opacity × √det Σ is the integral up to a constant: the same before and after.
        let mass = |l: [f64; 3], o: f64| sigmoid64(o) * l.iter().sum::<f64>().exp();
        assert!((mass(ls, o) - mass(fl, fo)).abs() < 1e-12 * mass(ls, o).max(1e-30) + 1e-15);
        assert!((0..3).all(|i| fl[i] > ls[i] && (2.0 * fl[i]).exp() >= s2));
        // s² = 0 changes nothing; an opaque, very thin Gaussian stays finite.
        let (same, so) = filtered(ls, o, 0.0);
        assert!((0..3).all(|i| (same[i] - ls[i]).abs() < 1e-12) && (so - o).abs() < 1e-9);
        let (tl, to) = filtered([-30.0, -30.0, -30.0], 40.0, 1.0);
        assert!(tl.iter().all(|x| x.is_finite()) && to.is_finite() && (to + 90.0).abs() < 1e-6);
    }

    #[test]
    fn f32_agrees_with_f64() {
        for (l, o, s2) in [([-3.0f32, -2.5, -6.0], 0.3f32, 0.01f32), ([-12.0, -11.0, -15.0], 9.0, 1e-7), ([0.5, 0.2, -1.0], -15.0, 3.0)] {
            let (a, b) = (filter_one(l, o, s2), filter_one(l.map(f64::from), f64::from(o), f64::from(s2)));
            let close = |x: f32, y: f64| (f64::from(x) - y).abs() <= 2e-5 * (1.0 + y.abs());
            assert!((0..3).all(|i| close(a.log_scales[i], b.log_scales[i]) && close(a.partials.scale_scale[i], b.partials.scale_scale[i])));
            assert!((0..3).all(|i| close(a.partials.logit_scale[i], b.partials.logit_scale[i])), "{a:?} {b:?}");
            assert!(close(a.logit, b.logit) && close(a.partials.logit_logit, b.partials.logit_logit), "{a:?} {b:?}");
        }
    }

    #[test]
    fn apply_revert_and_chain_round_trip() {
        let mut g = Gaussians {
            means: vec![[0.0; 3], [0.1, 0.0, 0.2]],
            log_scales: vec![[-3.0, -4.0, -6.0], [-2.0, -2.0, -9.0]],
            rotations: vec![[1.0, 0.0, 0.0, 0.0]; 2],
            opacity_logits: vec![0.5, 3.0],
            sh: vec![[[0.0; 3]; gs_core::sh::SH_COEFFS]; 2],
            sh_degree: 0,
        };
        let raw = g.clone();
        let mut s = Smoothing::new(vec![1e-4, 0.0]).unwrap();
        s.apply(&mut g).unwrap();
        assert!(s.applied() && g.log_scales[0][2] > raw.log_scales[0][2] && g.opacity_logits[0] < raw.opacity_logits[0]);
        assert_eq!(s.raw(&g), (&raw.log_scales[..], &raw.opacity_logits[..]));
        s.apply(&mut g).unwrap();
        assert_eq!(s.raw(&g).0, &raw.log_scales[..], "applying twice filters once");
        s.revert(&mut g);
        assert_eq!(g, raw);
        assert!(Smoothing::new(vec![1.0]).unwrap().apply(&mut g).is_err(), "rows must match");
        assert!(Smoothing::new(vec![f32::NAN, 0.0]).is_err() && Smoothing::new(vec![-1e-6]).is_err());
    }

    #[test]
    fn the_variance_follows_the_nearest_view() {
        let cams = gs_core::camera::camera_ring(8);
        let refs: Vec<&Camera> = cams.iter().collect();
        let g = Gaussians { means: vec![[0.0; 3], [1e6, 1e6, 1e6]], ..Gaussians::default() };
        let v = variances(&g, &refs, 0.01, 0.2);
        let nearest = refs.iter().map(|c| c.world_to_camera(Default::default()).z / c.intrinsics.fx.max(c.intrinsics.fy)).fold(f64::MAX, f64::min);
        assert!(((v[0] as f64) - 0.2 * nearest * nearest).abs() < 1e-6 * v[0] as f64);
        assert_eq!(v[1], v[0], "a centre no view sees takes the largest interval seen");
    }
}
