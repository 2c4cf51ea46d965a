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
//! [`LINK_REACH`]·dᵢ (so a held-out camera between two training cameras of a sparse ring, whose
//! nearest neighbour is on the other ring, lies on a link). The capsule of a link (or the ball
//! of a camera) has radius κ·min(dᵢ, dⱼ) (κ = `FloaterRule::path_clearance`), and only its
//! front part counts: a point must lie in front of the image plane of each camera of the link.
//! Walls close behind the cameras are behind them, so they stay.
//!
//! The scene's sparse points bound the capsules: a capsule's radius is at most
//! [`SURFACE_MARGIN`] of its link's distance to the nearest sparse point, since those points are
//! surfaces the training views observed. Without that bound, a sparse ring's long links are
//! chords through the object (the built-in scene at 10 training views lost 10,475 of its
//! ~12,000 Gaussians in one pass, held-out PSNR 14.7 → 6.6 dB).

use gs_core::glam::DVec3;
use gs_core::{Camera, Capsule};

/// Links reach at most this multiple of a camera's spacing: 2 spans a left-out view on a ring;
/// 3 also where the nearest camera is on the other ring of a sparse capture (pillars: spacing
/// 0.85, the cameras beside a held-out one 2.5 apart).
pub const LINK_REACH: f64 = 3.0;
/// Neighbours each camera links to at most.
pub const LINKS_PER_CAMERA: usize = 8;
/// A capsule reaches at most this share of the way from its link to the nearest sparse point.
pub const SURFACE_MARGIN: f64 = 0.5;
/// Sparse points a capsule's bound is measured against, at most (evenly strided).
const SURFACE_SAMPLES: usize = 20_000;
/// The free space in front of the training cameras' path.
#[derive(Debug, Clone, PartialEq)]
pub struct CapturePath {
    capsules: Vec<Capsule>,
}

impl CapturePath {
    /// The path of `cameras` with clearance κ = `clearance` (a share of the camera spacing),
    /// its capsules kept [`SURFACE_MARGIN`] of the way short of the sparse points `surface`
    /// (none given: no bound). Empty (contains nothing) when κ ≤ 0 or there are fewer than two
    /// cameras.
    pub fn new(cameras: &[&Camera], clearance: f64, surface: &[DVec3]) -> Self {
        if !(clearance > 0.0) || cameras.len() < 2 {
            return Self { capsules: Vec::new() };
        }
        let centres: Vec<DVec3> = cameras.iter().map(|c| c.center()).collect();
        let forward: Vec<DVec3> = cameras.iter().map(|c| c.rotation.transpose() * DVec3::Z).collect();
        // Every camera's others by distance (ties by index), computed once: the nearest sets
        // the spacing, the first few are the link candidates.
        let near: Vec<Vec<(f64, usize)>> = (0..centres.len())
            .map(|i| {
                let mut d: Vec<(f64, usize)> = (0..centres.len()).filter(|&j| j != i).map(|j| (centres[i].distance(centres[j]), j)).collect();
                d.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
                d
            })
            .collect();
        let spacing: Vec<f64> = near.iter().map(|d| d[0].0).collect();
        // Each camera's ball, then each link once (a BTreeSet keeps the order fixed).
        let mut capsules: Vec<Capsule> =
            (0..centres.len()).map(|i| Capsule { a: centres[i], b: centres[i], radius: clearance * spacing[i], fa: forward[i], fb: forward[i] }).collect();
        let links: std::collections::BTreeSet<(usize, usize)> = (0..centres.len())
            .flat_map(|i| {
                let reach = LINK_REACH * spacing[i];
                near[i].iter().take(LINKS_PER_CAMERA).filter(move |(d, _)| *d <= reach).map(move |&(_, j)| (i.min(j), i.max(j)))
            })
            .collect();
        capsules.extend(links.into_iter().map(|(i, j)| Capsule {
            a: centres[i],
            b: centres[j],
            radius: clearance * spacing[i].min(spacing[j]),
            fa: forward[i],
            fb: forward[j],
        }));
        if !surface.is_empty() {
            let stride = surface.len().div_ceil(SURFACE_SAMPLES);
            for c in &mut capsules {
                let nearest = surface.iter().step_by(stride).map(|p| c.distance_to_axis(*p)).fold(f64::INFINITY, f64::min);
                c.radius = c.radius.min(SURFACE_MARGIN * nearest);
            }
        }
        Self { capsules }
    }

    /// Whether point `p` lies in the free space in front of the path.
    pub fn contains(&self, p: DVec3) -> bool {
        self.capsules.iter().any(|c| c.contains(p))
    }

    /// The capsules (camera balls, then links), for a device that tests them itself.
    pub fn capsules(&self) -> &[Capsule] {
        &self.capsules
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
        let path = CapturePath::new(&train, 0.5, &[]);
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

    /// Two sparse rings (10 cameras each, radius 2.1, at heights 0.7 and 1.3, alternating in
    /// azimuth), as the pillars scene: a camera's nearest neighbour is on the other ring.
    fn two_rings() -> Vec<Camera> {
        (0..20)
            .map(|k| {
                let a = (k as f64 * 0.5) / 10.0 * std::f64::consts::TAU;
                let (r, z) = if k % 2 == 0 { (2.1, 0.7) } else { (1.9, 1.3) };
                let c = DVec3::new(r * a.cos(), r * a.sin(), z);
                Camera::look_at(64, 48, Intrinsics::new(60.0, 60.0, 32.0, 24.0), c, DVec3::new(0.0, 0.0, 0.3), DVec3::Z).unwrap()
            })
            .collect()
    }

    #[test]
    fn a_sparse_two_ring_capture_frees_the_front_of_a_left_out_camera() {
        let all = two_rings();
        let held = 8;
        let train: Vec<&Camera> = all.iter().enumerate().filter(|(k, _)| *k != held).map(|(_, c)| c).collect();
        let path = CapturePath::new(&train, 0.5, &[]);
        let c = all[held].center();
        let f = all[held].rotation.transpose() * DVec3::Z;
        for depth in [0.1, 0.2, 0.3] {
            assert!(path.contains(c + depth * f), "{depth} in front of the left-out camera");
        }
        assert!(!path.contains(c - 0.2 * f), "a wall 0.2 behind it");
        assert!(!path.contains(DVec3::new(0.0, 0.0, 0.3)), "the object");
    }

    #[test]
    fn sparse_points_bound_the_chords_of_a_sparse_ring() {
        // 10 cameras of radius 2: links of up to 3 spacings are chords that pass 1.2 from the
        // centre with capsules of radius 1.2 (κ = 1): without a bound the object is "free".
        let all = ring(10);
        let refs: Vec<&Camera> = all.iter().collect();
        let object = DVec3::new(0.3, 0.0, 0.0);
        assert!(CapturePath::new(&refs, 1.0, &[]).contains(object), "unbounded, the chords reach the object");
        let surface: Vec<DVec3> = (0..50).map(|k| DVec3::new(0.4 * (k as f64 * 0.7).cos(), 0.4 * (k as f64 * 0.7).sin(), 0.0)).collect();
        let bounded = CapturePath::new(&refs, 1.0, &surface);
        assert!(!bounded.contains(object) && !bounded.contains(DVec3::ZERO), "the sparse points keep the object");
        // Just in front of a camera, far from every point: still free.
        let c0 = all[0].center();
        assert!(bounded.contains(c0 * 0.93));
    }

    #[test]
    fn no_clearance_or_one_camera_frees_nothing() {
        let all = ring(8);
        let refs: Vec<&Camera> = all.iter().collect();
        let p = all[0].center() * 0.95;
        assert!(CapturePath::new(&refs, 0.5, &[]).contains(p));
        assert!(CapturePath::new(&refs, 0.0, &[]).is_empty());
        assert!(CapturePath::new(&refs[..1], 0.5, &[]).is_empty());
    }
}
