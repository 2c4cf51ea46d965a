//! Shared geometry: map views, the bilinear sampling convention, the reference→source pose and
//! the per-pixel plane homography H_rs = K_s (R_rs − t_rs Ñᵀ/D) K_r⁻¹ (docs/method.md §L_p).

use crate::error::{MvsError, Result};
use crate::Real;
use gs_core::glam::{DMat3, DVec3};
use gs_core::{Camera, Image};

/// A borrowed row-major `[H][W][C]` map in f32 or f64 (rendered normals, distances, depths,
/// grey images). `From<&Image>` gives the f32 view of a [`gs_core::Image`].
#[derive(Debug, Clone, Copy)]
pub struct MapView<'a, T> {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Values per pixel.
    pub channels: usize,
    /// The buffer, `width × height × channels` values.
    pub data: &'a [T],
}

impl<'a, T> MapView<'a, T> {
    /// Wraps a buffer; an error when its length is not `width × height × channels`.
    pub fn new(width: usize, height: usize, channels: usize, data: &'a [T]) -> Result<Self> {
        if let Some(m) = gs_core::image::grid_len_mismatch(width, height, channels, data.len()) {
            return Err(MvsError::InvalidInput(m));
        }
        Ok(Self {
            width,
            height,
            channels,
            data,
        })
    }

    /// Checks that this map is `camera.width × camera.height × channels`; `name` labels errors.
    pub fn expect_size(&self, camera: &Camera, channels: usize, name: &str) -> Result<()> {
        if self.width != camera.width as usize
            || self.height != camera.height as usize
            || self.channels != channels
        {
            return Err(MvsError::SizeMismatch {
                map: name.to_string(),
                expected: format!("{}x{}x{}", camera.width, camera.height, channels),
                got: format!("{}x{}x{}", self.width, self.height, self.channels),
            });
        }
        Ok(())
    }
}

impl<'a> From<&'a Image> for MapView<'a, f32> {
    fn from(img: &'a Image) -> Self {
        Self {
            width: img.width(),
            height: img.height(),
            channels: img.channels(),
            data: img.data(),
        }
    }
}

/// Bilinear sample of a 1-channel map at continuous pixel coordinates `(u, v)` with its
/// derivatives `(value, ∂/∂u, ∂/∂v)`. Convention (reference README §2): a coordinate c
/// interpolates pixels `floor(c − 0.5)` and `floor(c − 0.5) + 1` with weight `frac(c − 0.5)`;
/// taps outside the image are clamped to the edge. Callers check that `(u, v)` lies inside.
#[inline]
pub fn sample_bilinear_grad<T: Real>(
    data: &[T],
    width: usize,
    height: usize,
    u: T,
    v: T,
) -> (T, T, T) {
    let half = T::from_f64(0.5);
    // Keep the tap arithmetic bounded even for positions the caller did not clip.
    let x = (u - half).max(T::from_f64(-1.0)).min(T::from_usize(width));
    let y = (v - half).max(T::from_f64(-1.0)).min(T::from_usize(height));
    // Floor by truncation (x, y are finite in [−1, size], so this is `floor` exactly, without
    // the libm call that showed at 4 % of an L_p iteration, and in the type itself).
    let (x0, y0) = (x.floor_index(), y.floor_index());
    let fx = x - T::from_isize(x0);
    let fy = y - T::from_isize(y0);
    let cx = |i: isize| i.clamp(0, width as isize - 1) as usize;
    let cy = |j: isize| j.clamp(0, height as isize - 1) as usize;
    let (xa, xb, ya, yb) = (cx(x0), cx(x0 + 1), cy(y0), cy(y0 + 1));
    let i00 = data[ya * width + xa];
    let i10 = data[ya * width + xb];
    let i01 = data[yb * width + xa];
    let i11 = data[yb * width + xb];
    let top = i00 + (i10 - i00) * fx;
    let bottom = i01 + (i11 - i01) * fx;
    let value = top + (bottom - top) * fy;
    let du = (i10 - i00) * (T::ONE - fy) + (i11 - i01) * fy;
    let dv = bottom - top;
    (value, du, dv)
}

/// Bilinear sample without derivatives (same convention as [`sample_bilinear_grad`]).
#[inline]
pub fn sample_bilinear<T: Real>(data: &[T], width: usize, height: usize, u: T, v: T) -> T {
    sample_bilinear_grad(data, width, height, u, v).0
}

/// The plane-induced homography H_rs = K_s (R_rs − t_rs nᵀ/d) K_r⁻¹ of docs/method.md §L_p for a
/// plane `{x : n·x + d = 0}` in reference-camera coordinates (rendered normal Ñ, unnormalised,
/// and rendered distance D = −Ñ·x). It maps homogeneous reference pixels `(u, v, 1)` to
/// homogeneous source pixels.
pub fn plane_homography(
    reference: &Camera,
    source: &Camera,
    normal: DVec3,
    distance: f64,
) -> DMat3 {
    let (r_rs, t_rs) = reference.relative_pose_to(source);
    let outer = DMat3::from_cols(t_rs * normal.x, t_rs * normal.y, t_rs * normal.z);
    source.intrinsics.matrix()
        * (r_rs - outer * (1.0 / distance))
        * reference.intrinsics.inverse_matrix()
}

/// Per reference/source pair constants in the kernel's float type.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PairGeometry<T> {
    pub r_fx: T,
    pub r_fy: T,
    pub r_cx: T,
    pub r_cy: T,
    pub s_fx: T,
    pub s_fy: T,
    pub s_cx: T,
    pub s_cy: T,
    /// R_rs, row-major.
    pub rot: [T; 9],
    /// t_rs.
    pub t: [T; 3],
    /// K_s R_rs, row-major.
    pub a: [T; 9],
    /// K_s t_rs.
    pub kt: [T; 3],
    pub src_w: T,
    pub src_h: T,
}

/// The rows of a row-major 3×3 matrix, each padded to four values (a WGSL `vec4` record field).
#[cfg(feature = "wgpu")]
pub(crate) fn padded_rows<T: Real>(m: &[T; 9]) -> [[T; 4]; 3] {
    [0, 1, 2].map(|r| [m[3 * r], m[3 * r + 1], m[3 * r + 2], T::ZERO])
}

/// A 3-vector padded to four values (a WGSL `vec4` record field).
#[cfg(feature = "wgpu")]
pub(crate) fn padded<T: Real>(v: &[T; 3]) -> [T; 4] {
    [v[0], v[1], v[2], T::ZERO]
}

#[inline]
pub(crate) fn mat_vec<T: Real>(m: &[T; 9], x: [T; 3]) -> [T; 3] {
    [
        m[0] * x[0] + m[1] * x[1] + m[2] * x[2],
        m[3] * x[0] + m[4] * x[1] + m[5] * x[2],
        m[6] * x[0] + m[7] * x[1] + m[8] * x[2],
    ]
}

#[inline]
pub(crate) fn mat_t_vec<T: Real>(m: &[T; 9], x: [T; 3]) -> [T; 3] {
    [
        m[0] * x[0] + m[3] * x[1] + m[6] * x[2],
        m[1] * x[0] + m[4] * x[1] + m[7] * x[2],
        m[2] * x[0] + m[5] * x[1] + m[8] * x[2],
    ]
}

#[inline]
pub(crate) fn dot3<T: Real>(a: [T; 3], b: [T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn row_major<T: Real>(m: DMat3) -> [T; 9] {
    let r = m.transpose().to_cols_array(); // columns of the transpose are the rows of m
    r.map(T::from_f64)
}

impl<T: Real> PairGeometry<T> {
    pub fn new(reference: &Camera, source: &Camera) -> Self {
        let (r_rs, t_rs) = reference.relative_pose_to(source);
        let ks = source.intrinsics.matrix();
        let (ri, si) = (&reference.intrinsics, &source.intrinsics);
        Self {
            r_fx: T::from_f64(ri.fx),
            r_fy: T::from_f64(ri.fy),
            r_cx: T::from_f64(ri.cx),
            r_cy: T::from_f64(ri.cy),
            s_fx: T::from_f64(si.fx),
            s_fy: T::from_f64(si.fy),
            s_cx: T::from_f64(si.cx),
            s_cy: T::from_f64(si.cy),
            rot: row_major(r_rs),
            t: t_rs.to_array().map(T::from_f64),
            a: row_major(ks * r_rs),
            kt: (ks * t_rs).to_array().map(T::from_f64),
            src_w: T::from_f64(source.width as f64),
            src_h: T::from_f64(source.height as f64),
        }
    }

    /// The reference ray K_r⁻¹(u, v, 1) (z = 1).
    #[inline]
    pub fn ref_ray(&self, u: T, v: T) -> [T; 3] {
        [
            (u - self.r_cx) / self.r_fx,
            (v - self.r_cy) / self.r_fy,
            T::ONE,
        ]
    }

    /// The reference rays of every pixel centre of a `width × height` reference image, as
    /// the x and y tables of [`PairGeometry::ref_ray`] (`ref_ray(px + ½, py + ½) = [x[px],
    /// y[py], 1]`, the same arithmetic): a patch loop reads them instead of dividing twice per
    /// sample.
    pub fn ref_ray_tables(&self, width: usize, height: usize) -> (Vec<T>, Vec<T>) {
        let hp = T::from_f64(0.5);
        let xs = (0..width).map(|px| self.ref_ray(T::from_usize(px) + hp, hp)[0]).collect();
        let ys = (0..height).map(|py| self.ref_ray(hp, T::from_usize(py) + hp)[1]).collect();
        (xs, ys)
    }

    /// The source ray K_s⁻¹(u, v, 1).
    #[inline]
    pub fn src_ray(&self, u: T, v: T) -> [T; 3] {
        [
            (u - self.s_cx) / self.s_fx,
            (v - self.s_cy) / self.s_fy,
            T::ONE,
        ]
    }

    /// x_s = R_rs x_r + t_rs.
    #[inline]
    pub fn map_to_source(&self, x: [T; 3]) -> [T; 3] {
        let y = mat_vec(&self.rot, x);
        [y[0] + self.t[0], y[1] + self.t[1], y[2] + self.t[2]]
    }

    /// x_r = R_rsᵀ (x_s − t_rs).
    #[inline]
    pub fn map_to_reference(&self, x: [T; 3]) -> [T; 3] {
        mat_t_vec(
            &self.rot,
            [x[0] - self.t[0], x[1] - self.t[1], x[2] - self.t[2]],
        )
    }

    /// Whether `(u, v)` lies in the open source rectangle (0, W) × (0, H) (NaN fails).
    #[inline]
    pub fn inside_source(&self, u: T, v: T) -> bool {
        u > T::ZERO && u < self.src_w && v > T::ZERO && v < self.src_h
    }

    /// Homogeneous warp of the reference ray `q` (= K_r⁻¹ p̄) by the plane (n, 1/D):
    /// `w = K_s R_rs q − K_s t_rs · m` with `m = nᵀq / D`. Returns `(w, m)`.
    #[inline]
    pub fn warp(&self, q: [T; 3], n: [T; 3], inv_d: T) -> ([T; 3], T) {
        let m = dot3(n, q) * inv_d;
        let aq = mat_vec(&self.a, q);
        (
            [
                aq[0] - self.kt[0] * m,
                aq[1] - self.kt[1] * m,
                aq[2] - self.kt[2] * m,
            ],
            m,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gs_core::Intrinsics;

    fn cameras() -> (Camera, Camera) {
        let k = Intrinsics::new(60.0, 62.0, 32.5, 23.0);
        let r = Camera::look_at(
            64,
            48,
            k,
            DVec3::new(0.3, -3.0, 2.0),
            DVec3::new(0.0, 0.2, 0.0),
            DVec3::Z,
        )
        .unwrap();
        let s = Camera::look_at(
            64,
            48,
            k,
            DVec3::new(1.4, -2.6, 1.7),
            DVec3::new(0.1, 0.0, 0.1),
            DVec3::Z,
        )
        .unwrap();
        (r, s)
    }

    /// The ray tables hold exactly (bit for bit) what `ref_ray` computes per pixel centre.
    #[test]
    fn ray_tables_are_ref_ray_bit_for_bit() {
        let (r, s) = cameras();
        let g = PairGeometry::<f32>::new(&r, &s);
        let (xs, ys) = g.ref_ray_tables(64, 48);
        assert_eq!((xs.len(), ys.len()), (64, 48));
        for (py, y) in ys.iter().enumerate() {
            for (px, x) in xs.iter().enumerate() {
                let q = g.ref_ray(px as f32 + 0.5, py as f32 + 0.5);
                assert_eq!([x.to_bits(), y.to_bits(), 1f32.to_bits()], q.map(f32::to_bits));
            }
        }
    }

    /// Warping with H equals projecting the 3D intersection of the pixel ray with the plane.
    #[test]
    fn homography_matches_ray_plane_intersection() {
        let (r, s) = cameras();
        // World plane through p0 with normal nw.
        let nw = DVec3::new(0.2, -0.1, 1.0).normalize();
        let p0 = DVec3::new(0.1, 0.0, 0.05);
        // Reference camera-space plane: n_c·x + d = 0 with n_c = R nw, d = −n_c·x0.
        let n_c = r.rotation * nw;
        let d = -n_c.dot(r.world_to_camera(p0));
        let h = plane_homography(&r, &s, n_c, d);
        let g = PairGeometry::<f64>::new(&r, &s);
        let mut worst: f64 = 0.0;
        for &(u, v) in &[
            (0.5, 0.5),
            (32.5, 23.0),
            (10.25, 40.75),
            (63.5, 47.5),
            (45.0, 5.0),
        ] {
            let ray = r.ray(u, v);
            let t = -d / n_c.dot(ray); // depth along z (ray has z = 1)
            let x_world = r.camera_to_world(ray * t);
            let (expected, _) = s.project(x_world).unwrap();
            let w = h * DVec3::new(u, v, 1.0);
            let got = (w.x / w.z, w.y / w.z);
            worst = worst
                .max((got.0 - expected.x).abs())
                .max((got.1 - expected.y).abs());
            // The kernel's factored form.
            let (wk, _) = g.warp(g.ref_ray(u, v), n_c.to_array(), 1.0 / d);
            worst = worst
                .max((wk[0] / wk[2] - expected.x).abs())
                .max((wk[1] / wk[2] - expected.y).abs());
            // And in f32.
            let g32 = PairGeometry::<f32>::new(&r, &s);
            let (w32, _) = g32.warp(
                g32.ref_ray(u as f32, v as f32),
                n_c.as_vec3().to_array(),
                1.0 / d as f32,
            );
            assert!(((w32[0] / w32[2]) as f64 - expected.x).abs() < 1e-3);
            assert!(((w32[1] / w32[2]) as f64 - expected.y).abs() < 1e-3);
        }
        assert!(worst < 1e-9, "homography error {worst} px");
    }

    #[test]
    fn bilinear_convention_and_gradient() {
        // 3×2 image; value = column + 10·row at pixel centres.
        let data: Vec<f64> = (0..6)
            .map(|k| (k % 3) as f64 + 10.0 * (k / 3) as f64)
            .collect();
        // At a pixel centre the sample is the pixel value.
        assert_eq!(sample_bilinear(&data, 3, 2, 1.5, 0.5), 1.0);
        // Halfway between centres (u = 2.0) interpolates columns 1 and 2.
        assert!((sample_bilinear(&data, 3, 2, 2.0, 1.0) - 6.5).abs() < 1e-12);
        let (_, du, dv) = sample_bilinear_grad(&data, 3, 2, 1.2, 1.1);
        assert!((du - 1.0).abs() < 1e-12 && (dv - 10.0).abs() < 1e-12);
        // Within half a pixel of the border the taps are clamped: constant, zero derivative.
        let (val, du, _) = sample_bilinear_grad(&data, 3, 2, 0.2, 0.5);
        assert_eq!((val, du), (0.0, 0.0));
        let (val, du, _) = sample_bilinear_grad(&data, 3, 2, 2.9, 0.5);
        assert_eq!((val, du), (2.0, 0.0));
    }

    /// The truncation floor gives the bits of the `floor` formula everywhere, pixel centres and
    /// edges, outside positions and NaN included.
    #[test]
    fn bilinear_sampler_matches_the_floor_formula_bit_for_bit() {
        let (w, h) = (17usize, 11usize);
        let mut rng = gs_core::Rng::new(5);
        let data: Vec<f32> = (0..w * h).map(|_| rng.uniform()).collect();
        let reference = |u: f32, v: f32| {
            let x = (u - 0.5).max(-1.0).min(w as f32);
            let y = (v - 0.5).max(-1.0).min(h as f32);
            let (x0f, y0f) = (x.floor(), y.floor());
            let (fx, fy) = (x - x0f, y - y0f);
            let c = |i: f32, n: usize| (i as isize).clamp(0, n as isize - 1) as usize;
            let (xa, xb, ya, yb) = (c(x0f, w), c(x0f + 1.0, w), c(y0f, h), c(y0f + 1.0, h));
            let (i00, i10, i01, i11) = (data[ya * w + xa], data[ya * w + xb], data[yb * w + xa], data[yb * w + xb]);
            let (top, bottom) = (i00 + (i10 - i00) * fx, i01 + (i11 - i01) * fx);
            (top + (bottom - top) * fy, (i10 - i00) * (1.0 - fy) + (i11 - i01) * fy, bottom - top)
        };
        let mut points: Vec<(f32, f32)> = (0..20_000).map(|_| (rng.uniform() * 21.0 - 2.0, rng.uniform() * 15.0 - 2.0)).collect();
        for k in -2..20 {
            points.extend([(k as f32, 0.5), (k as f32 + 0.5, 3.0), (1.0, k as f32 + 0.5), (f32::NAN, 2.0), (f32::INFINITY, -1e9)]);
        }
        for (u, v) in points {
            let (a, b) = (sample_bilinear_grad(&data, w, h, u, v), reference(u, v));
            assert_eq!([a.0, a.1, a.2].map(f32::to_bits), [b.0, b.1, b.2].map(f32::to_bits), "at ({u}, {v})");
        }
    }
}
