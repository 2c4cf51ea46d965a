//! Block regions on the ground plane (docs/architecture.md §Partitioned training): a grid of
//! `nu × nv` core rectangles that tile the whole plane (the outer ones open towards infinity,
//! so every point belongs to exactly one core), cut at weighted quantiles of the camera
//! centres so each block trains about as many pixels; and each core grown by a margin, the
//! region whose views and points a block trains on.

use serde::{Deserialize, Serialize};

/// A core region: `[u0, u1) × [v0, v1)` on the ground axes, `None` for an open side.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Region {
    /// Lower and upper bound along `u`.
    pub u: [Option<f64>; 2],
    /// Lower and upper bound along `v`.
    pub v: [Option<f64>; 2],
}

impl Region {
    /// Whether the ground coordinates `p` lie in the region (lower bounds inclusive, upper
    /// bounds exclusive, so neighbouring cores never share a point).
    pub fn contains(&self, p: [f64; 2]) -> bool {
        let inside = |x: f64, [lo, hi]: [Option<f64>; 2]| lo.is_none_or(|lo| x >= lo) && hi.is_none_or(|hi| x < hi);
        inside(p[0], self.u) && inside(p[1], self.v)
    }

    /// The region grown by `margin` × its size on each bounded side, open sides closed at the
    /// capture's `extent`: the finite rectangle a block's views and points are chosen from.
    pub fn grown(&self, margin: f64, extent: &Rect) -> Rect {
        let axis = |[lo, hi]: [Option<f64>; 2], a: usize| {
            let (l, h) = (lo.unwrap_or(extent.min[a]), hi.unwrap_or(extent.max[a]));
            let (l, h) = (l.min(h), h.max(l));
            let m = margin * (h - l);
            (lo.map_or(extent.min[a].min(l), |_| l - m), hi.map_or(extent.max[a].max(h), |_| h + m))
        };
        let (u, v) = (axis(self.u, 0), axis(self.v, 1));
        Rect { min: [u.0, v.0], max: [u.1, v.1] }
    }

    /// The bounds in words, e.g. "u in [-1.20, 3.40) m, v unbounded".
    pub fn describe(&self) -> String {
        let side = |name: &str, [lo, hi]: [Option<f64>; 2]| match (lo, hi) {
            (None, None) => format!("{name} unbounded"),
            (Some(l), None) => format!("{name} ≥ {l:.2}"),
            (None, Some(h)) => format!("{name} < {h:.2}"),
            (Some(l), Some(h)) => format!("{name} in [{l:.2}, {h:.2})"),
        };
        format!("{}, {}", side("u", self.u), side("v", self.v))
    }

    /// Checks bounds read from a file: finite, each lower bound below its upper bound.
    pub fn validate(&self) -> std::result::Result<(), String> {
        for [lo, hi] in [self.u, self.v] {
            if lo.is_some_and(|x| !x.is_finite()) || hi.is_some_and(|x| !x.is_finite()) {
                return Err("a bound is not a finite number".into());
            }
            if let (Some(l), Some(h)) = (lo, hi) {
                if l >= h {
                    return Err(format!("its lower bound {l} is not below its upper bound {h}"));
                }
            }
        }
        Ok(())
    }
}

/// A finite rectangle on the ground axes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Rect {
    /// Lower corner `(u, v)`.
    pub min: [f64; 2],
    /// Upper corner `(u, v)`.
    pub max: [f64; 2],
}

impl Rect {
    /// Whether `p` lies in the closed rectangle.
    pub fn contains(&self, p: [f64; 2]) -> bool {
        (0..2).all(|a| p[a] >= self.min[a] && p[a] <= self.max[a])
    }

    /// The bounding rectangle of `pts` (`None` when empty).
    pub fn around(pts: impl IntoIterator<Item = [f64; 2]>) -> Option<Self> {
        let mut it = pts.into_iter();
        let first = it.next()?;
        Some(it.fold(Self { min: first, max: first }, |r, p| Self {
            min: [r.min[0].min(p[0]), r.min[1].min(p[1])],
            max: [r.max[0].max(p[0]), r.max[1].max(p[1])],
        }))
    }

    /// Side lengths along `u` and `v`.
    pub fn size(&self) -> [f64; 2] {
        [self.max[0] - self.min[0], self.max[1] - self.min[1]]
    }
}

/// The grid `(nu, nv)` with `nu · nv = blocks` whose cells are closest to square over a
/// capture of `size` (cuts go across its longer side first: a street becomes strips).
pub fn grid_shape(blocks: usize, size: [f64; 2]) -> (usize, usize) {
    let aspect = (size[0].max(1e-12) / size[1].max(1e-12)).ln();
    (1..=blocks)
        .filter(|nu| blocks % nu == 0)
        .map(|nu| (nu, blocks / nu))
        .min_by(|a, b| {
            let cost = |(nu, nv): (usize, usize)| (aspect - (nu as f64 / nv as f64).ln()).abs();
            cost(*a).total_cmp(&cost(*b)).then(b.0.cmp(&a.0))
        })
        .unwrap_or((1, 1))
}

/// The `parts − 1` cut positions that split `items` (position, weight) into `parts` runs of
/// about equal weight: each cut halfway between the last item of one run and the first of
/// the next. Fewer cuts when items run out (ties stay in one run).
pub fn weighted_cuts(items: &[(f64, f64)], parts: usize) -> Vec<f64> {
    let mut sorted: Vec<(f64, f64)> = items.to_vec();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = sorted.iter().map(|x| x.1).sum();
    let mut cuts = Vec::new();
    let mut acc = 0.0;
    for w in sorted.windows(2) {
        acc += w[0].1;
        let next = total * (cuts.len() + 1) as f64 / parts as f64;
        if cuts.len() + 1 < parts && acc >= next - 1e-12 && w[1].0 > w[0].0 {
            cuts.push(0.5 * (w[0].0 + w[1].0));
        }
    }
    cuts
}

/// The core regions of a `nu × nv` grid over the cameras `(ground coordinates, weight)`: `nu`
/// strips along `u` cut at the weighted quantiles of all cameras, then each strip cut into `nv`
/// along `v` at the quantiles of its own cameras. Row-major (strip by strip); fewer regions when
/// the cameras do not allow as many distinct cuts.
pub fn core_regions(cams: &[([f64; 2], f64)], nu: usize, nv: usize) -> Vec<Region> {
    let along_u: Vec<(f64, f64)> = cams.iter().map(|(p, w)| (p[0], *w)).collect();
    let bounds = |cuts: &[f64]| -> Vec<[Option<f64>; 2]> {
        let mut edges: Vec<Option<f64>> = vec![None];
        edges.extend(cuts.iter().map(|&c| Some(c)));
        edges.push(None);
        edges.windows(2).map(|w| [w[0], w[1]]).collect()
    };
    let mut regions = Vec::new();
    for u in bounds(&weighted_cuts(&along_u, nu)) {
        let strip = Region { u, v: [None, None] };
        let in_strip: Vec<(f64, f64)> = cams.iter().filter(|(p, _)| strip.contains(*p)).map(|(p, w)| (p[1], *w)).collect();
        for v in bounds(&weighted_cuts(&in_strip, nv)) {
            regions.push(Region { u, v });
        }
    }
    regions
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_long_capture_is_cut_into_strips() {
        assert_eq!(grid_shape(4, [12.0, 3.0]), (4, 1));
        assert_eq!(grid_shape(4, [5.0, 5.0]), (2, 2));
        assert_eq!(grid_shape(6, [3.0, 2.0]), (3, 2));
        assert_eq!(grid_shape(1, [1.0, 9.0]), (1, 1));
    }

    #[test]
    fn cuts_balance_the_weight() {
        let items: Vec<(f64, f64)> = (0..12).map(|i| (i as f64, 1.0)).collect();
        assert_eq!(weighted_cuts(&items, 3), vec![3.5, 7.5]);
        // Heavy items on the left pull the cut left.
        let heavy: Vec<(f64, f64)> = (0..12).map(|i| (i as f64, if i < 3 { 3.0 } else { 1.0 })).collect();
        assert_eq!(weighted_cuts(&heavy, 2), vec![2.5]);
        // All cameras at one place: no cut can separate them.
        assert!(weighted_cuts(&[(1.0, 1.0); 5], 3).is_empty());
    }

    #[test]
    fn cores_tile_the_plane_and_grow_by_the_margin() {
        let cams: Vec<([f64; 2], f64)> = (0..40).map(|i| ([(i % 10) as f64, (i / 10) as f64], 1.0)).collect();
        let cores = core_regions(&cams, 2, 2);
        assert_eq!(cores.len(), 4);
        for p in [[-100.0, -100.0], [4.5, 1.5], [4.51, 1.49], [100.0, 3.0], [0.0, 50.0]] {
            assert_eq!(cores.iter().filter(|r| r.contains(p)).count(), 1, "{p:?}");
        }
        let extent = Rect { min: [0.0, 0.0], max: [9.0, 3.0] };
        let g = cores[0].grown(0.2, &extent);
        assert_eq!(g.min, [0.0, 0.0]);
        assert!((g.max[0] - (4.5 + 0.2 * 4.5)).abs() < 1e-12, "{g:?}");
        assert!(Region { u: [Some(1.0), Some(1.0)], v: [None, None] }.validate().is_err());
        assert!(Region { u: [Some(f64::NAN), None], v: [None, None] }.validate().is_err());
    }
}
