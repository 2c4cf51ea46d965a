//! The capture path as free space: where the cameras went, nothing stands.
//!
//! Every training camera stood at its centre, and the camera moved between neighbouring
//! positions, so the space just in front of that path is empty. No training view contradicts
//! a splat there: it lies beside or between the cameras, outside the narrow near part of their
//! frusta, and far views see it only edge-on against the surface behind it, which it copies.
//! A held-out camera on the path then looks through it: a veil (docs/method.md §Floaters).
//!
//! The free region is a chain of capsules. Camera i's spacing dᵢ is the distance to its nearest
//! other training camera. Each camera links to its neighbours: the nearest few, no farther than
//! [`LINK_REACH`]·dᵢ (so a held-out camera between two training cameras lies on a link). The
//! capsule of a link (or the ball of a lone camera) has radius κ·min(dᵢ, dⱼ) (κ =
//! `FloaterRule::path_clearance`), and only its front part counts: a point must lie within
//! [`FRONT_CONE_DEG`] of the direction the cameras look. Walls close behind the cameras are
//! behind them, so they stay.

use gs_core::glam::DVec3;
use gs_core::Camera;

/// Links reach at most this multiple of a camera's spacing (2 spans a left-out view).
pub const LINK_REACH: f64 = 2.5;
/// Neighbours each camera links to at most.
pub const LINKS_PER_CAMERA: usize = 4;
/// Half-angle of the cone in front of the path that counts as free, degrees.
pub const FRONT_CONE_DEG: f64 = 60.0;

/// One capsule of the path: the segment a–b swept by a ball of `radius`, facing `forward`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Capsule {
    a: DVec3,
    b: DVec3,
    radius: f64,
    forward: DVec3,
}

impl Capsule {
    fn contains(&self, p: DVec3, cos_cone: f64) -> bool {
        let ab = self.b - self.a;
        let len2 = ab.length_squared();
        let t = if len2 > 0.0 { ((p - self.a).dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
        let q = self.a + t * ab;
        let off = p - q;
        let dist = off.length();
        dist < self.radius && off.dot(self.forward) > cos_cone * dist
    }
}

/// The free space in front of the training cameras' path.
#[derive(Debug, Clone, PartialEq)]
pub struct CapturePath {
    capsules: Vec<Capsule>,
    cos_cone: f64,
}

impl CapturePath {
    /// The path of `cameras` with clearance κ = `clearance` (a share of the camera spacing).
    /// Empty (contains nothing) when κ ≤ 0 or there are fewer than two cameras.
    pub fn new(cameras: &[&Camera], clearance: f64) -> Self {
        let cos_cone = FRONT_CONE_DEG.to_radians().cos();
        if !(clearance > 0.0) || cameras.len() < 2 {
            return Self { capsules: Vec::new(), cos_cone };
        }
        let centres: Vec<DVec3> = cameras.iter().map(|c| c.center()).collect();
        let forward: Vec<DVec3> = cameras.iter().map(|c| c.rotation.transpose() * DVec3::Z).collect();
        let spacing: Vec<f64> = (0..centres.len())
            .map(|i| (0..centres.len()).filter(|&j| j != i).map(|j| centres[i].distance(centres[j])).fold(f64::INFINITY, f64::min))
            .collect();
        // Each camera's ball, then each link once (a BTreeSet keeps the order fixed).
        let mut capsules: Vec<Capsule> =
            (0..centres.len()).map(|i| Capsule { a: centres[i], b: centres[i], radius: clearance * spacing[i], forward: forward[i] }).collect();
        let mut links = std::collections::BTreeSet::new();
        for i in 0..centres.len() {
            let mut near: Vec<(f64, usize)> = (0..centres.len()).filter(|&j| j != i).map(|j| (centres[i].distance(centres[j]), j)).collect();
            near.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            links.extend(near.iter().take(LINKS_PER_CAMERA).filter(|(d, _)| *d <= LINK_REACH * spacing[i]).map(|&(_, j)| (i.min(j), i.max(j))));
        }
        for (i, j) in links {
            let f = (forward[i] + forward[j]).normalize_or_zero();
            if f != DVec3::ZERO {
                // Cameras facing opposite ways have no common front.
                capsules.push(Capsule { a: centres[i], b: centres[j], radius: clearance * spacing[i].min(spacing[j]), forward: f });
            }
        }
        Self { capsules, cos_cone }
    }

    /// Whether point `p` lies in the free space in front of the path.
    pub fn contains(&self, p: DVec3) -> bool {
        self.capsules.iter().any(|c| c.contains(p, self.cos_cone))
    }

    /// Capsules (camera balls and links) of the path.
    pub fn len(&self) -> usize {
        self.capsules.len()
    }

    /// Whether the path holds no free space at all.
    pub fn is_empty(&self) -> bool {
        self.capsules.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gs_core::camera::Intrinsics;

    /// `n` cameras on a ring of radius 2 at height 0, looking at the origin.
    fn ring(n: usize) -> Vec<Camera> {
        (0..n)
            .map(|k| {
                let a = k as f64 / n as f64 * std::f64::consts::TAU;
                let c = DVec3::new(2.0 * a.cos(), 2.0 * a.sin(), 0.0);
                Camera::look_at(64, 48, Intrinsics::new(60.0, 60.0, 32.0, 24.0), c, DVec3::ZERO, DVec3::Z).unwrap()
            })
            .collect()
    }

    #[test]
    fn in_front_of_a_left_out_camera_is_free_behind_and_inside_is_not() {
        let all = ring(16);
        // Leave out camera 4 (as a held-out view would be).
        let train: Vec<&Camera> = all.iter().enumerate().filter(|(k, _)| *k != 4).map(|(_, c)| c).collect();
        let path = CapturePath::new(&train, 0.5);
        let spacing = all[0].center().distance(all[1].center());
        let held = all[4].center();
        let inward = -held.normalize();
        // 0.3 spacings in front of the left-out camera: free.
        assert!(path.contains(held + 0.3 * spacing * inward));
        // Behind the ring (a wall 0.3 spacings behind the cameras): not free.
        assert!(!path.contains(held - 0.3 * spacing * inward));
        // The object at the centre and a point one spacing in front: not free.
        assert!(!path.contains(DVec3::ZERO));
        assert!(!path.contains(held + 1.0 * spacing * inward));
        // Just in front of a training camera: free.
        let c0 = all[0].center();
        assert!(path.contains(c0 - 0.2 * spacing * c0.normalize()));
    }

    #[test]
    fn no_clearance_or_one_camera_frees_nothing() {
        let all = ring(8);
        let refs: Vec<&Camera> = all.iter().collect();
        let p = all[0].center() * 0.95;
        assert!(CapturePath::new(&refs, 0.5).contains(p));
        assert!(CapturePath::new(&refs, 0.0).is_empty());
        assert!(CapturePath::new(&refs[..1], 0.5).is_empty());
    }
}
