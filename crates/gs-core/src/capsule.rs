//! A capsule of free space: the points near a segment that lie in front of both its ends.
//!
//! gs-train's capture-path rule (docs/method.md §Floaters) chains these between the training
//! cameras; the host tests them here in f64, and a device holding the model tests them in f32
//! (gs-raster `mark_capsules_resident`), leaving to [`Capsule::contains`] every point too close
//! to a boundary for f32 to decide.

use glam::DVec3;

/// The segment a–b swept by a ball of `radius`, cut to the points in front of the image plane
/// of the camera at each end (`fa`, `fb`: their unit viewing directions). A ball where a = b.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Capsule {
    /// One end of the axis.
    pub a: DVec3,
    /// The other end.
    pub b: DVec3,
    /// Distance from the axis within which a point is inside.
    pub radius: f64,
    /// The viewing direction at `a`: a point must satisfy (p − a)·fa > 0.
    pub fa: DVec3,
    /// The viewing direction at `b`: (p − b)·fb > 0.
    pub fb: DVec3,
}

impl Capsule {
    /// Distance from `p` to the capsule's segment.
    pub fn distance_to_axis(&self, p: DVec3) -> f64 {
        let ab = self.b - self.a;
        let len2 = ab.length_squared();
        let t = if len2 > 0.0 { ((p - self.a).dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
        (p - (self.a + t * ab)).length()
    }

    /// Whether `p` lies inside: in front of both ends and closer to the axis than the radius.
    /// A non-finite point is not inside.
    pub fn contains(&self, p: DVec3) -> bool {
        if (p - self.a).dot(self.fa) <= 0.0 || (p - self.b).dot(self.fb) <= 0.0 {
            return false; // behind a camera of the link
        }
        self.distance_to_axis(p) < self.radius
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_link_holds_its_front_and_a_ball_its_front_half() {
        let link = Capsule { a: DVec3::ZERO, b: DVec3::X, radius: 0.5, fa: DVec3::Y, fb: DVec3::Y };
        assert!(link.contains(DVec3::new(0.5, 0.3, 0.0)));
        assert!(!link.contains(DVec3::new(0.5, -0.3, 0.0)), "behind both cameras");
        assert!(!link.contains(DVec3::new(0.5, 0.6, 0.0)), "too far from the axis");
        assert!(!link.contains(DVec3::new(1.6, 0.1, 0.0)), "beyond b: its distance is to b, not to the line");
        assert!((link.distance_to_axis(DVec3::new(2.0, 0.0, 0.0)) - 1.0).abs() < 1e-15);
        let ball = Capsule { b: DVec3::ZERO, ..link };
        assert!(ball.contains(DVec3::new(0.0, 0.4, 0.1)) && !ball.contains(DVec3::new(0.0, -0.4, 0.1)));
        assert!(!ball.contains(DVec3::splat(f64::NAN)));
    }
}
