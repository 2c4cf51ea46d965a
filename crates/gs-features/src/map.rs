//! Feature maps F = f(I) (docs/method.md §L_f): `[H'][W'][C]` row-major, sampled bilinearly at
//! IMAGE pixel coordinates with the pixel-centre convention, with the gradient w.r.t. (u, v)
//! that L_f needs to push the reprojected position p_s' (and so the plane depth z_r).

use crate::error::{FeatureError, Result};
use crate::weights::{f16_to_f32, f32_to_f16};

/// How feature values are stored in memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum StoragePrecision {
    /// 4 bytes per value (exact network output).
    #[default]
    F32,
    /// 2 bytes per value (IEEE half, round to nearest even; relative error ≤ 2⁻¹¹ ≈ 4.9e-4):
    /// halves the per-image cache (conv2_2 at 800×600: 30.7 MB instead of 61.4 MB).
    F16,
}

#[derive(Debug, Clone, PartialEq)]
enum Storage {
    F32(Vec<f32>),
    F16(Vec<u16>),
}

/// A feature map `[height][width][channels]` at `stride` image pixels per feature pixel.
///
/// Feature pixel `k` covers image pixels `[stride·k, stride·(k+1))`; its centre sits at image
/// coordinate `stride·(k + 0.5)`, i.e. feature coordinate `u / stride` with feature-pixel centres
/// at `k + 0.5` — the same pixel-centre convention as images (docs/architecture.md §Conventions).
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureMap {
    width: usize,
    height: usize,
    channels: usize,
    stride: f32,
    storage: Storage,
}

/// The result of [`FeatureMap::sample_bilinear`]: F(u, v) and its partial derivatives.
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureSample {
    /// The interpolated feature vector (length = channels).
    pub value: Vec<f32>,
    /// ∂F/∂u (per image pixel).
    pub d_du: Vec<f32>,
    /// ∂F/∂v (per image pixel).
    pub d_dv: Vec<f32>,
    /// Whether (u, v) lies inside the image rectangle `[0, stride·W') × [0, stride·H')`.
    pub inside: bool,
}

impl FeatureMap {
    /// Wraps a row-major `[height][width][channels]` f32 buffer; `stride` is the number of
    /// image pixels per feature pixel (2 for conv2_2, 4 for conv3_3). Errors on a size mismatch,
    /// an empty map, a non-finite value or a non-positive stride.
    pub fn from_vec(
        width: usize,
        height: usize,
        channels: usize,
        stride: f32,
        data: Vec<f32>,
    ) -> Result<Self> {
        if width == 0 || height == 0 || channels == 0 {
            return Err(FeatureError::InvalidParameter(format!(
                "feature map size {width}x{height}x{channels} is empty"
            )));
        }
        if !(stride.is_finite() && stride > 0.0) {
            return Err(FeatureError::InvalidParameter(format!("feature stride {stride} must be > 0")));
        }
        if let Some(m) = gs_core::image::grid_len_mismatch(width, height, channels, data.len()) {
            return Err(FeatureError::InvalidParameter(format!("feature map: {m}")));
        }
        if let Some(i) = data.iter().position(|v| !v.is_finite()) {
            return Err(FeatureError::InvalidParameter(format!("feature value {i} is not finite")));
        }
        Ok(Self { width, height, channels, stride, storage: Storage::F32(data) })
    }

    /// Width W' in feature pixels.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height H' in feature pixels.
    pub fn height(&self) -> usize {
        self.height
    }
    /// Channels C.
    pub fn channels(&self) -> usize {
        self.channels
    }
    /// Image pixels per feature pixel.
    pub fn stride(&self) -> f32 {
        self.stride
    }
    /// Storage precision.
    pub fn precision(&self) -> StoragePrecision {
        match self.storage {
            Storage::F32(_) => StoragePrecision::F32,
            Storage::F16(_) => StoragePrecision::F16,
        }
    }
    /// Bytes held by the values (the cache budget per image).
    pub fn memory_bytes(&self) -> usize {
        match &self.storage {
            Storage::F32(v) => v.len() * 4,
            Storage::F16(v) => v.len() * 2,
        }
    }

    /// The same map stored at `precision` (f32 → f16 rounds to nearest even).
    pub fn with_precision(self, precision: StoragePrecision) -> Self {
        let storage = match (self.storage, precision) {
            (Storage::F32(v), StoragePrecision::F16) => {
                Storage::F16(v.iter().map(|&x| f32_to_f16(x)).collect())
            }
            (Storage::F16(v), StoragePrecision::F32) => {
                Storage::F32(v.iter().map(|&h| f16_to_f32(h)).collect())
            }
            (s, _) => s,
        };
        Self { storage, ..self }
    }

    /// The values as f32, row-major `[H'][W'][C]` (a copy for f16 storage).
    pub fn to_f32_vec(&self) -> Vec<f32> {
        match &self.storage {
            Storage::F32(v) => v.clone(),
            Storage::F16(v) => v.iter().map(|&h| f16_to_f32(h)).collect(),
        }
    }

    /// Value of channel `c` at feature pixel (column `x`, row `y`); panics when out of range,
    /// like slice indexing.
    #[inline]
    pub fn get(&self, x: usize, y: usize, c: usize) -> f32 {
        assert!(x < self.width && y < self.height && c < self.channels);
        let i = (y * self.width + x) * self.channels + c;
        match &self.storage {
            Storage::F32(v) => v[i],
            Storage::F16(v) => f16_to_f32(v[i]),
        }
    }

    /// Copies the feature vector of feature pixel `(x, y)` into `out` (length = channels).
    pub fn pixel_into(&self, x: usize, y: usize, out: &mut [f32]) {
        assert!(x < self.width && y < self.height && out.len() == self.channels);
        let i = (y * self.width + x) * self.channels;
        match &self.storage {
            Storage::F32(v) => out.copy_from_slice(&v[i..i + self.channels]),
            Storage::F16(v) => {
                for (o, &h) in out.iter_mut().zip(&v[i..i + self.channels]) {
                    *o = f16_to_f32(h);
                }
            }
        }
    }

    /// Bilinear sample at IMAGE pixel coordinates `(u, v)` with ∂F/∂u and ∂F/∂v.
    /// See [`FeatureMap::sample_bilinear_into`] for the conventions.
    pub fn sample_bilinear(&self, u: f32, v: f32) -> FeatureSample {
        let c = self.channels;
        let mut s =
            FeatureSample { value: vec![0.0; c], d_du: vec![0.0; c], d_dv: vec![0.0; c], inside: false };
        s.inside = self.sample_bilinear_into(u, v, &mut s.value, Some((&mut s.d_du, &mut s.d_dv)));
        s
    }

    /// Allocation-free bilinear sample at IMAGE pixel coordinates `(u, v)` (pixel centres at
    /// `i + 0.5`). The feature coordinate is `(u / stride, v / stride)` and feature pixel `k`'s
    /// centre is at `k + 0.5` there. Outside the centres of the border feature pixels the sample
    /// is clamped to the border (and the derivative across it is 0). Writes F(u, v) into
    /// `value` and, when given, ∂F/∂u and ∂F/∂v (per image pixel) into `grad`. Returns whether
    /// (u, v) lies inside `[0, stride·W') × [0, stride·H')`; a non-finite (u, v) gives zeros and
    /// `false`. Panics if a slice length differs from the channel count (a caller bug).
    pub fn sample_bilinear_into(
        &self,
        u: f32,
        v: f32,
        value: &mut [f32],
        grad: Option<(&mut [f32], &mut [f32])>,
    ) -> bool {
        let c = self.channels;
        assert_eq!(value.len(), c, "value slice length must equal the channel count");
        if !(u.is_finite() && v.is_finite()) {
            value.fill(0.0);
            if let Some((gu, gv)) = grad {
                gu.fill(0.0);
                gv.fill(0.0);
            }
            return false;
        }
        let inv = 1.0 / self.stride;
        let inside = u >= 0.0
            && v >= 0.0
            && u < self.stride * self.width as f32
            && v < self.stride * self.height as f32;
        // Continuous index with feature-pixel centres at integers.
        let fx = u * inv - 0.5;
        let fy = v * inv - 0.5;
        let (x0, x1, tx, dx_ok) = axis(fx, self.width);
        let (y0, y1, ty, dy_ok) = axis(fy, self.height);
        let w00 = (1.0 - tx) * (1.0 - ty);
        let w10 = tx * (1.0 - ty);
        let w01 = (1.0 - tx) * ty;
        let w11 = tx * ty;
        let i00 = (y0 * self.width + x0) * c;
        let i10 = (y0 * self.width + x1) * c;
        let i01 = (y1 * self.width + x0) * c;
        let i11 = (y1 * self.width + x1) * c;
        let su = if dx_ok { inv } else { 0.0 };
        let sv = if dy_ok { inv } else { 0.0 };
        macro_rules! body {
            ($data:expr, $conv:expr) => {{
                let d = $data;
                let (a, b, e, f) = (&d[i00..i00 + c], &d[i10..i10 + c], &d[i01..i01 + c], &d[i11..i11 + c]);
                match grad {
                    Some((gu, gv)) => {
                        assert!(gu.len() == c && gv.len() == c, "gradient slice lengths must equal the channel count");
                        for k in 0..c {
                            let (p00, p10, p01, p11) = ($conv(a[k]), $conv(b[k]), $conv(e[k]), $conv(f[k]));
                            value[k] = w00 * p00 + w10 * p10 + w01 * p01 + w11 * p11;
                            gu[k] = su * ((p10 - p00) * (1.0 - ty) + (p11 - p01) * ty);
                            gv[k] = sv * ((p01 - p00) * (1.0 - tx) + (p11 - p10) * tx);
                        }
                    }
                    None => {
                        for k in 0..c {
                            value[k] = w00 * $conv(a[k]) + w10 * $conv(b[k]) + w01 * $conv(e[k]) + w11 * $conv(f[k]);
                        }
                    }
                }
            }};
        }
        match &self.storage {
            Storage::F32(d) => body!(d, |x: f32| x),
            Storage::F16(d) => body!(d, f16_to_f32),
        }
        inside
    }
}

/// Clamped bilinear axis: (lower index, upper index, fraction, derivative non-zero).
#[inline]
fn axis(f: f32, n: usize) -> (usize, usize, f32, bool) {
    let max = (n - 1) as f32;
    if n == 1 || f <= 0.0 {
        return (0, 0, 0.0, false);
    }
    if f >= max {
        return (n - 1, n - 1, 0.0, false);
    }
    let i = f.floor();
    let i0 = i as usize;
    (i0, (i0 + 1).min(n - 1), f - i, true)
}

/// The norm floor of docs/method.md §L_f: cos(a, b) = a·b / (max(‖a‖, ε)·max(‖b‖, ε)).
pub const COSINE_EPS: f32 = 1e-8;

/// cos(a, b) = a·b / (max(‖a‖, 1e-8)·max(‖b‖, 1e-8)) (docs/method.md §L_f), accumulated in f64.
pub fn cosine(a: &[f32], b: &[f32]) -> f32 {
    cosine_parts(a, b).0
}

fn cosine_parts(a: &[f32], b: &[f32]) -> (f32, f64, f64, bool) {
    assert_eq!(a.len(), b.len(), "cosine of vectors of different lengths");
    let (mut ab, mut aa, mut bb) = (0f64, 0f64, 0f64);
    for (&x, &y) in a.iter().zip(b) {
        ab += x as f64 * y as f64;
        aa += x as f64 * x as f64;
        bb += y as f64 * y as f64;
    }
    let eps = COSINE_EPS as f64;
    let na = aa.sqrt().max(eps);
    let nb_raw = bb.sqrt();
    let nb = nb_raw.max(eps);
    ((ab / (na * nb)) as f32, na, nb, nb_raw > eps)
}

/// cos(a, b) and ∂cos/∂b written into `d_b` (the side whose sample position moves in L_f).
pub fn cosine_with_grad(a: &[f32], b: &[f32], d_b: &mut [f32]) -> f32 {
    assert_eq!(d_b.len(), b.len());
    let (cos, na, nb, b_unclamped) = cosine_parts(a, b);
    for ((g, &x), &y) in d_b.iter_mut().zip(a).zip(b) {
        let mut d = x as f64 / (na * nb);
        if b_unclamped {
            d -= cos as f64 * y as f64 / (nb * nb);
        }
        *g = d as f32;
    }
    cos
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp_map(w: usize, h: usize, c: usize, stride: f32) -> FeatureMap {
        // Channel k holds (k + 1)·(x + 10·y) at feature pixel (x, y): bilinear-exact.
        let mut d = Vec::new();
        for y in 0..h {
            for x in 0..w {
                for k in 0..c {
                    d.push((k + 1) as f32 * (x as f32 + 10.0 * y as f32));
                }
            }
        }
        FeatureMap::from_vec(w, h, c, stride, d).unwrap()
    }

    #[test]
    fn pixel_centre_convention_maps_image_to_feature_pixels() {
        for stride in [2.0f32, 4.0] {
            let m = ramp_map(5, 4, 2, stride);
            // The centre of feature pixel (k, j) is at image (s(k + 0.5), s(j + 0.5)).
            for j in 0..4 {
                for k in 0..5 {
                    let s = m.sample_bilinear(stride * (k as f32 + 0.5), stride * (j as f32 + 0.5));
                    assert!(s.inside);
                    assert_eq!(s.value[0], k as f32 + 10.0 * j as f32);
                    assert_eq!(s.value[1], 2.0 * (k as f32 + 10.0 * j as f32));
                }
            }
            // Between centres the ramp is linear: ∂/∂u = 1/stride, ∂/∂v = 10/stride (channel 0).
            let s = m.sample_bilinear(stride * 1.8, stride * 2.1);
            assert!((s.value[0] - (1.3 + 10.0 * 1.6)).abs() < 1e-5);
            assert!((s.d_du[0] - 1.0 / stride).abs() < 1e-6);
            assert!((s.d_dv[0] - 10.0 / stride).abs() < 1e-6);
            assert!((s.d_du[1] - 2.0 / stride).abs() < 1e-6);
            // Image pixel centres 0.5 and 1.5 average to feature pixel 0 at stride 2.
            if stride == 2.0 {
                let a = m.sample_bilinear(0.5, 1.0).value[0];
                assert_eq!(a, 0.0); // clamped left of the first centre
                let b = m.sample_bilinear(3.0, 1.0).value[0];
                assert_eq!(b, 1.0);
            }
        }
    }

    #[test]
    fn border_clamping_and_non_finite_coordinates() {
        let m = ramp_map(3, 2, 1, 2.0);
        let s = m.sample_bilinear(-5.0, 1.0);
        assert!(!s.inside);
        assert_eq!(s.value[0], 0.0);
        assert_eq!(s.d_du[0], 0.0);
        let s = m.sample_bilinear(5.9, 3.9); // last image pixel centre region: clamped, inside
        assert!(s.inside);
        assert_eq!(s.value[0], 2.0 + 10.0);
        assert_eq!((s.d_du[0], s.d_dv[0]), (0.0, 0.0));
        assert!(!m.sample_bilinear(6.0, 1.0).inside);
        let s = m.sample_bilinear(f32::NAN, 1.0);
        assert!(!s.inside && s.value[0] == 0.0 && s.d_du[0] == 0.0);
        assert!(!m.sample_bilinear(1.0, f32::INFINITY).inside);
        let one = FeatureMap::from_vec(1, 1, 1, 4.0, vec![3.0]).unwrap();
        let s = one.sample_bilinear(1.0, 3.0);
        assert_eq!((s.value[0], s.d_du[0], s.inside), (3.0, 0.0, true));
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let mut d = Vec::new();
        let mut rng = gs_core::Rng::new(5);
        for _ in 0..(6 * 5 * 3) {
            d.push(rng.normal() as f32);
        }
        let m = FeatureMap::from_vec(6, 5, 3, 4.0, d).unwrap();
        for _ in 0..50 {
            let u = 2.5 + 18.0 * rng.uniform() as f32;
            let v = 2.5 + 14.0 * rng.uniform() as f32;
            let s = m.sample_bilinear(u, v);
            let h = 1e-2f32;
            let (p, q) = (m.sample_bilinear(u + h, v), m.sample_bilinear(u - h, v));
            let (r, t) = (m.sample_bilinear(u, v + h), m.sample_bilinear(u, v - h));
            for k in 0..3 {
                // Piecewise bilinear: skip samples straddling a cell edge.
                let fu = (u / 4.0 - 0.5).fract();
                let fv = (v / 4.0 - 0.5).fract();
                if fu > 0.01 && fu < 0.99 {
                    assert!(((p.value[k] - q.value[k]) / (2.0 * h) - s.d_du[k]).abs() < 2e-3);
                }
                if fv > 0.01 && fv < 0.99 {
                    assert!(((r.value[k] - t.value[k]) / (2.0 * h) - s.d_dv[k]).abs() < 2e-3);
                }
            }
        }
    }

    #[test]
    fn f16_storage_halves_memory_and_stays_close() {
        let m = ramp_map(7, 3, 4, 2.0);
        let h = m.clone().with_precision(StoragePrecision::F16);
        assert_eq!(h.memory_bytes() * 2, m.memory_bytes());
        assert_eq!(h.precision(), StoragePrecision::F16);
        let (a, b) = (m.sample_bilinear(5.3, 2.7), h.sample_bilinear(5.3, 2.7));
        for k in 0..4 {
            assert!((a.value[k] - b.value[k]).abs() <= 1e-3 * a.value[k].abs().max(1.0));
        }
        let back = h.with_precision(StoragePrecision::F32);
        assert_eq!(back.to_f32_vec(), m.to_f32_vec()); // small integers are exact in f16
    }

    #[test]
    fn from_vec_rejects_bad_input() {
        assert!(FeatureMap::from_vec(0, 1, 1, 2.0, vec![]).is_err());
        assert!(FeatureMap::from_vec(2, 1, 1, 2.0, vec![1.0]).is_err());
        assert!(FeatureMap::from_vec(1, 1, 1, 0.0, vec![1.0]).is_err());
        assert!(FeatureMap::from_vec(1, 1, 1, 2.0, vec![f32::NAN]).is_err());
    }

    #[test]
    fn cosine_follows_the_spec_and_its_gradient_is_right() {
        assert!((cosine(&[1.0, 0.0], &[2.0, 0.0]) - 1.0).abs() < 1e-7);
        assert!(cosine(&[1.0, 0.0], &[0.0, 3.0]).abs() < 1e-7);
        assert_eq!(cosine(&[0.0, 0.0], &[0.0, 0.0]), 0.0);
        let a = [0.3f32, -1.2, 0.8, 2.0];
        let b = [1.1f32, 0.4, -0.7, 0.9];
        let mut g = [0f32; 4];
        let c0 = cosine_with_grad(&a, &b, &mut g);
        assert!((c0 - cosine(&a, &b)).abs() < 1e-7);
        for k in 0..4 {
            let h = 1e-3;
            let (mut bp, mut bm) = (b, b);
            bp[k] += h;
            bm[k] -= h;
            let fd = (cosine(&a, &bp) - cosine(&a, &bm)) / (2.0 * h);
            assert!((fd - g[k]).abs() < 1e-3, "{k}: {fd} vs {}", g[k]);
        }
        // b = 0 (e.g. all-ReLU-dead features): finite gradient, no NaN.
        let z = [0f32; 4];
        let c = cosine_with_grad(&a, &z, &mut g);
        assert_eq!(c, 0.0);
        assert!(g.iter().all(|v| v.is_finite()));
    }
}
