//! A depth map as a colour image for people: near yellow, far dark blue (viridis stops),
//! scaled between the 2nd and 98th percentile of the valid depths so that one stray value
//! does not flatten the map; pixels without depth are black.

use gs_core::Image;

/// Viridis at 0, 0.25, 0.5, 0.75 and 1 (matplotlib's values, rounded).
const STOPS: [[f32; 3]; 5] =
    [[0.267, 0.005, 0.329], [0.229, 0.322, 0.546], [0.128, 0.567, 0.551], [0.369, 0.789, 0.383], [0.993, 0.906, 0.144]];

/// The viridis colour at `t` in [0, 1] (linear between the stops).
fn viridis(t: f32) -> [f32; 3] {
    let x = t.clamp(0.0, 1.0) * 4.0;
    let i = (x as usize).min(3);
    let f = x - i as f32;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    [a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), a[2] + f * (b[2] - a[2])]
}

/// Colours a one-channel depth image (0, negative or non-finite = no depth): near depths
/// bright, far depths dark. Returns the image and the depth range `(near, far)` the colours
/// span (`None` when no pixel has a depth).
pub fn depth_colormap(depth: &Image) -> (Image, Option<(f32, f32)>) {
    let (w, h) = (depth.width(), depth.height());
    let mut out = Image::new(w, h, 3).expect("the depth image's own size is valid");
    let mut valid: Vec<f32> = depth.data().iter().copied().filter(|d| d.is_finite() && *d > 0.0).collect();
    if valid.is_empty() {
        return (out, None);
    }
    valid.sort_unstable_by(f32::total_cmp);
    let at = |q: f64| valid[((valid.len() - 1) as f64 * q).round() as usize];
    let (near, far) = (at(0.02), at(0.98));
    let span = (far - near).max(f32::EPSILON * far.abs().max(1.0));
    for (o, &d) in out.data_mut().chunks_exact_mut(3).zip(depth.data()) {
        if d.is_finite() && d > 0.0 {
            o.copy_from_slice(&viridis(1.0 - (d - near) / span));
        }
    }
    (out, Some((near, far)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn near_is_bright_far_is_dark_and_holes_are_black() {
        let d = Image::from_vec(4, 1, 1, vec![1.0, 2.0, 0.0, f32::NAN]).unwrap();
        let (img, range) = depth_colormap(&d);
        assert_eq!(range, Some((1.0, 2.0)));
        let px = |x: usize| [img.get(x, 0, 0), img.get(x, 0, 1), img.get(x, 0, 2)];
        assert!(px(0).iter().sum::<f32>() > px(1).iter().sum::<f32>() + 1.0);
        assert_eq!(px(2), [0.0; 3]);
        assert_eq!(px(3), [0.0; 3]);
    }

    #[test]
    fn an_image_without_depth_has_no_range() {
        let d = Image::from_vec(2, 1, 1, vec![0.0, 0.0]).unwrap();
        assert_eq!(depth_colormap(&d).1, None);
    }
}
