//! Procedural shapes of the suite objects: surfaces of revolution (cups, vases, bowls,
//! pedestals), tubes swept along curves (handles, knots, springs, arches), a plate with a
//! rectangular hole (a window frame) and stepped blocks (stairs). Each is built from its own
//! vertices (no shared vertices between shapes), wound outward, with analytic shading normals.

use crate::geometry::{Builder, Material};
use glam::DVec3;
use std::f64::consts::TAU;

impl Builder {
    /// A surface of revolution about the vertical axis through `centre`: the profile
    /// `(radius, height)` points, walked with the solid on the left (e.g. a cup: out along the
    /// bottom, up the outside, over the rim, down the inside), revolved in `segments` steps.
    /// Smooth around the axis, flat along the profile (each profile segment gets its own ring
    /// of vertices, so rims and corners stay sharp).
    pub(crate) fn lathe(
        &mut self,
        centre: DVec3,
        profile: &[[f64; 2]],
        segments: usize,
        m: Material,
    ) {
        for w in profile.windows(2) {
            let ([r0, z0], [r1, z1]) = (w[0], w[1]);
            let (dr, dz) = (r1 - r0, z1 - z0);
            let len = dr.hypot(dz);
            if len == 0.0 {
                continue;
            }
            // Outward = right of the walking direction in the (r, z) half-plane.
            let (nr, nz) = (dz / len, -dr / len);
            let ring = |b: &mut Builder, r: f64, z: f64| -> Vec<u32> {
                (0..segments)
                    .map(|j| {
                        let a = TAU * j as f64 / segments as f64;
                        let (c, s) = (a.cos(), a.sin());
                        let n = DVec3::new(nr * c, nr * s, nz);
                        b.vertex(centre + DVec3::new(r * c, r * s, z), n)
                    })
                    .collect()
            };
            let lo = ring(self, r0, z0);
            let hi = ring(self, r1, z1);
            for j in 0..segments {
                let j1 = (j + 1) % segments;
                self.quad([lo[j], lo[j1], hi[j1], hi[j]], None, m, true);
            }
        }
    }

    /// A tube of radius `radius` swept along the polyline `path` (parallel-transported frames,
    /// `sides` vertices around). `closed` joins the end to the start (the frame's twist is spread
    /// along the loop); otherwise both ends get flat caps.
    pub(crate) fn tube(
        &mut self,
        path: &[DVec3],
        radius: f64,
        sides: usize,
        closed: bool,
        m: Material,
    ) {
        let n = path.len();
        let tangent = |i: usize| -> DVec3 {
            let (a, b) = if closed {
                (path[(i + n - 1) % n], path[(i + 1) % n])
            } else {
                (path[i.saturating_sub(1)], path[(i + 1).min(n - 1)])
            };
            (b - a).normalize()
        };
        let t0 = tangent(0);
        let seed = if t0.z.abs() < 0.9 { DVec3::Z } else { DVec3::X };
        let mut normals = vec![(seed - t0 * seed.dot(t0)).normalize()];
        for i in 1..n {
            let (ta, tb) = (tangent(i - 1), tangent(i));
            normals.push(transport(normals[i - 1], ta, tb));
        }
        if closed {
            // Rotate frames progressively so that the last one meets the first.
            let back = transport(normals[n - 1], tangent(n - 1), t0);
            let twist = signed_angle(back, normals[0], t0);
            for (i, nrm) in normals.iter_mut().enumerate() {
                let a = twist * i as f64 / n as f64;
                *nrm = glam::DQuat::from_axis_angle(tangent(i), a) * *nrm;
            }
        }
        let rings: Vec<Vec<u32>> = (0..n)
            .map(|i| {
                let t = tangent(i);
                let u = normals[i];
                let v = t.cross(u);
                (0..sides)
                    .map(|j| {
                        let a = TAU * j as f64 / sides as f64;
                        let d = u * a.cos() + v * a.sin();
                        self.vertex(path[i] + radius * d, d)
                    })
                    .collect()
            })
            .collect();
        let segs = if closed { n } else { n - 1 };
        for i in 0..segs {
            let (a, b) = (&rings[i], &rings[(i + 1) % n]);
            for j in 0..sides {
                let j1 = (j + 1) % sides;
                self.quad([a[j], a[j1], b[j1], b[j]], None, m, true);
            }
        }
        if !closed {
            for (i, out) in [(0, -tangent(0)), (n - 1, tangent(n - 1))] {
                let c = self.vertex(path[i], out);
                let rim: Vec<u32> = (0..sides)
                    .map(|j| {
                        let p = self.positions[rings[i][j] as usize];
                        self.vertex(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64), out)
                    })
                    .collect();
                for j in 0..sides {
                    self.triangle([c, rim[j], rim[(j + 1) % sides]], out, m, false);
                }
            }
        }
    }

    /// A box given by its corner ranges `lo..hi` (axis-aligned, flat shaded).
    pub(crate) fn aabox(&mut self, lo: DVec3, hi: DVec3, m: Material) {
        self.cuboid((lo + hi) * 0.5, (hi - lo) * 0.5, glam::DMat3::IDENTITY, m);
    }

    /// An upright plate in the x–z plane (thickness along y, centred on `centre`, its bottom at
    /// `centre.z`) of outer size `w × h` with a rectangular hole of `hole_w × hole_h` whose
    /// bottom is `sill` above the plate's bottom: a window frame, watertight, flat shaded.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn frame(
        &mut self,
        centre: DVec3,
        w: f64,
        h: f64,
        depth: f64,
        hole: [f64; 3],
        m: Material,
    ) {
        let [hole_w, hole_h, sill] = hole;
        let outer = [[-w / 2.0, 0.0], [w / 2.0, 0.0], [w / 2.0, h], [-w / 2.0, h]];
        let inner = [
            [-hole_w / 2.0, sill],
            [hole_w / 2.0, sill],
            [hole_w / 2.0, sill + hole_h],
            [-hole_w / 2.0, sill + hole_h],
        ];
        let at = |[x, z]: [f64; 2], y: f64| centre + DVec3::new(x, y, z);
        let (yf, yb) = (-depth / 2.0, depth / 2.0);
        for (y, out) in [(yf, -DVec3::Y), (yb, DVec3::Y)] {
            for i in 0..4 {
                let i1 = (i + 1) % 4;
                let q = [
                    at(outer[i], y),
                    at(outer[i1], y),
                    at(inner[i1], y),
                    at(inner[i], y),
                ];
                self.flat_quad(q, out, m);
            }
        }
        for i in 0..4 {
            let i1 = (i + 1) % 4;
            // Outer side faces point away from the plate's centre, inner ones into the hole.
            let mid_o = 0.5
                * (DVec3::new(outer[i][0], 0.0, outer[i][1])
                    + DVec3::new(outer[i1][0], 0.0, outer[i1][1]));
            let mid_i = 0.5
                * (DVec3::new(inner[i][0], 0.0, inner[i][1])
                    + DVec3::new(inner[i1][0], 0.0, inner[i1][1]));
            let hole_c = DVec3::new(0.0, 0.0, sill + hole_h / 2.0);
            let out_o = side_normal(mid_o - DVec3::new(0.0, 0.0, h / 2.0));
            let out_i = side_normal(hole_c - mid_i);
            self.flat_quad(
                [
                    at(outer[i], yf),
                    at(outer[i1], yf),
                    at(outer[i1], yb),
                    at(outer[i], yb),
                ],
                out_o,
                m,
            );
            self.flat_quad(
                [
                    at(inner[i], yf),
                    at(inner[i1], yf),
                    at(inner[i1], yb),
                    at(inner[i], yb),
                ],
                out_i,
                m,
            );
        }
    }

    /// Stairs along +x from `origin` (its lowest front corner): step `k` spans
    /// `[x_k, x_k + run]`, is `heights[k]` tall and `width` deep along y. Watertight, flat shaded.
    pub(crate) fn stairs(
        &mut self,
        origin: DVec3,
        run: f64,
        width: f64,
        heights: &[f64],
        m: Material,
    ) {
        let n = heights.len();
        let p = |x: f64, y: f64, z: f64| origin + DVec3::new(x, y, z);
        let x_end = run * n as f64;
        self.flat_quad(
            [
                p(0.0, 0.0, 0.0),
                p(x_end, 0.0, 0.0),
                p(x_end, width, 0.0),
                p(0.0, width, 0.0),
            ],
            -DVec3::Z,
            m,
        );
        let mut prev = 0.0;
        for (k, &h) in heights.iter().enumerate() {
            let (x0, x1) = (run * k as f64, run * (k + 1) as f64);
            self.flat_quad(
                [
                    p(x0, 0.0, h),
                    p(x1, 0.0, h),
                    p(x1, width, h),
                    p(x0, width, h),
                ],
                DVec3::Z,
                m,
            );
            for (y, out) in [(0.0, -DVec3::Y), (width, DVec3::Y)] {
                self.flat_quad(
                    [p(x0, y, 0.0), p(x1, y, 0.0), p(x1, y, h), p(x0, y, h)],
                    out,
                    m,
                );
            }
            // The riser between the previous step's height and this one.
            if h != prev {
                let out = if h > prev { -DVec3::X } else { DVec3::X };
                let (a, b) = (prev.min(h), prev.max(h));
                self.flat_quad(
                    [
                        p(x0, 0.0, a),
                        p(x0, width, a),
                        p(x0, width, b),
                        p(x0, 0.0, b),
                    ],
                    out,
                    m,
                );
            }
            prev = h;
        }
        self.flat_quad(
            [
                p(x_end, 0.0, 0.0),
                p(x_end, width, 0.0),
                p(x_end, width, prev),
                p(x_end, 0.0, prev),
            ],
            DVec3::X,
            m,
        );
    }

    /// A flat quad with its own four vertices, facing `out`.
    fn flat_quad(&mut self, q: [DVec3; 4], out: DVec3, m: Material) {
        self.rectangle(q, out, m);
    }
}

/// The x/z-plane normal of a frame side: the dominant axis of `d`.
fn side_normal(d: DVec3) -> DVec3 {
    if d.x.abs() > d.z.abs() {
        DVec3::new(d.x.signum(), 0.0, 0.0)
    } else {
        DVec3::new(0.0, 0.0, d.z.signum())
    }
}

/// Parallel transport of normal `n` from tangent `ta` to tangent `tb` (rotation taking ta to tb).
fn transport(n: DVec3, ta: DVec3, tb: DVec3) -> DVec3 {
    let q = glam::DQuat::from_rotation_arc(ta, tb);
    let r = q * n;
    (r - tb * r.dot(tb)).normalize()
}

/// Angle from `a` to `b` about `axis` (both perpendicular to it), in radians.
fn signed_angle(a: DVec3, b: DVec3, axis: DVec3) -> f64 {
    a.cross(b).dot(axis).atan2(a.dot(b))
}

/// Points of a closed curve `f(t)`, `t` in `[0, 1)`, sampled at `n` steps.
pub(crate) fn closed_curve(n: usize, f: impl Fn(f64) -> DVec3) -> Vec<DVec3> {
    (0..n).map(|i| f(i as f64 / n as f64)).collect()
}

/// Points of an open curve `f(t)`, `t` in `[0, 1]`, sampled at `n + 1` steps.
pub(crate) fn open_curve(n: usize, f: impl Fn(f64) -> DVec3) -> Vec<DVec3> {
    (0..=n).map(|i| f(i as f64 / n as f64)).collect()
}
