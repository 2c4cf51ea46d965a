//! The growth region of a block of a partitioned run (docs/architecture.md §Partitioned
//! training): a rectangle of the ground plane, unbounded vertically. A block keeps only its
//! core's Gaussians at the merge, so it densifies only inside its grown region and its budget
//! counts only the surface there ([`crate::budget`]); what its views see beyond the region stays
//! at the initial sparse points, optimised but never grown. Without a region (any ordinary run)
//! every Gaussian may grow.

use serde::{Deserialize, Serialize};

/// A ground rectangle `[min, max]` in the frame (`origin`, unit axes `u`, `v` on the ground):
/// a point `p` lies inside when `((p − origin)·u, (p − origin)·v)` does.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GrowthRegion {
    /// A point on the ground.
    pub origin: [f64; 3],
    /// First ground axis (unit).
    pub u: [f64; 3],
    /// Second ground axis (unit, orthogonal to `u`).
    pub v: [f64; 3],
    /// Lower corner in (u, v).
    pub min: [f64; 2],
    /// Upper corner in (u, v).
    pub max: [f64; 2],
}

/// Coordinates of `p` along the ground axes `u`, `v` from `origin`: ((p − origin)·u,
/// (p − origin)·v). The one formula of a ground frame, for gs-partition's frame and the
/// regions it hands to training alike.
pub fn ground_coords(origin: [f64; 3], u: [f64; 3], v: [f64; 3], p: [f64; 3]) -> [f64; 2] {
    let d = [p[0] - origin[0], p[1] - origin[1], p[2] - origin[2]];
    let dot = |a: [f64; 3]| d[0] * a[0] + d[1] * a[1] + d[2] * a[2];
    [dot(u), dot(v)]
}

impl GrowthRegion {
    /// The ground coordinates of `p` ([`ground_coords`]).
    pub fn coords(&self, p: [f64; 3]) -> [f64; 2] {
        ground_coords(self.origin, self.u, self.v, p)
    }

    /// Whether a Gaussian's mean lies in the region.
    pub fn contains(&self, mean: [f32; 3]) -> bool {
        let [a, b] = self.coords(mean.map(f64::from));
        a >= self.min[0] && a <= self.max[0] && b >= self.min[1] && b <= self.max[1]
    }

    /// Checks a region from a settings file or `--set`: finite, unit orthogonal axes, a
    /// non-empty rectangle; the message names the setting.
    pub fn validate(&self) -> Result<(), String> {
        let all = self.origin.iter().chain(&self.u).chain(&self.v).chain(&self.min).chain(&self.max);
        if !all.into_iter().all(|x| x.is_finite()) {
            return Err("densify.region: every coordinate must be a finite number".into());
        }
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let (uu, vv, uv) = (dot(self.u, self.u), dot(self.v, self.v), dot(self.u, self.v));
        if (uu - 1.0).abs() > 1e-6 || (vv - 1.0).abs() > 1e-6 || uv.abs() > 1e-6 {
            return Err(format!(
                "densify.region: u and v must be orthogonal unit axes (|u|² = {uu:.6}, |v|² = {vv:.6}, u·v = {uv:.6})"
            ));
        }
        if !(self.min[0] < self.max[0] && self.min[1] < self.max[1]) {
            return Err(format!(
                "densify.region: min {:?} must lie below max {:?} on both axes",
                self.min, self.max
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tilted() -> GrowthRegion {
        let s = std::f64::consts::FRAC_1_SQRT_2;
        GrowthRegion { origin: [1.0, 0.0, 0.0], u: [s, s, 0.0], v: [-s, s, 0.0], min: [0.0, -1.0], max: [2.0, 1.0] }
    }

    #[test]
    fn inside_by_ground_coordinates_at_any_height() {
        let r = tilted();
        assert!(r.contains([1.0, 0.0, 0.0]));
        assert!(r.contains([1.7, 0.7, 1e6]), "the region is unbounded vertically");
        assert!(!r.contains([0.0, 0.0, 0.0]), "behind the origin along u");
        assert!(!r.contains([1.0, 3.0, 0.0]));
        assert!(r.validate().is_ok());
    }

    #[test]
    fn bad_regions_are_named() {
        let mut r = tilted();
        r.u = [1.0, 1.0, 0.0];
        assert!(r.validate().unwrap_err().contains("orthogonal unit axes"));
        let mut r = tilted();
        r.max = [0.0, 1.0];
        assert!(r.validate().unwrap_err().contains("must lie below max"));
        let mut r = tilted();
        r.origin[2] = f64::NAN;
        assert!(r.validate().unwrap_err().contains("finite"));
    }
}
