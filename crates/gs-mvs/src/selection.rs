//! Source-view selection (docs/method.md §Schedule): candidates per view precomputed once with
//! [`gs_core::source_view_candidates`] (axis within 30°, centre distance in (0.01·r, 1.5·r),
//! nearest 8), then N = 3 per iteration, top-N or random-N (seeded).

use crate::error::{MvsError, Result};
use gs_core::{Camera, NeighbourRule, Rng, source_view_candidates};

/// How the N source views are drawn from a view's candidates each iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SourceSelection {
    /// N distinct candidates at random (seeded) — the default of docs/method.md §Schedule.
    #[default]
    RandomN,
    /// The N nearest candidates (by centre distance), every iteration.
    TopN,
}

/// Per-view source candidates and the per-iteration choice of N source views.
#[derive(Debug, Clone, PartialEq)]
pub struct SourceViewSelector {
    candidates: Vec<Vec<usize>>,
    count: usize,
    mode: SourceSelection,
}

impl SourceViewSelector {
    /// Precomputes the candidates of every camera with `rule`; `count` = N (3 in the paper).
    pub fn new(
        cameras: &[&Camera],
        rule: &NeighbourRule,
        count: usize,
        mode: SourceSelection,
    ) -> Result<Self> {
        if count == 0 {
            return Err(MvsError::InvalidConfig(
                "the number of source views N must be positive".into(),
            ));
        }
        if !(rule.max_angle_deg.is_finite()
            && rule.min_distance.is_finite()
            && rule.max_distance.is_finite())
        {
            return Err(MvsError::InvalidConfig(format!(
                "neighbour rule has non-finite values: {rule:?}"
            )));
        }
        Ok(Self {
            candidates: source_view_candidates(cameras, rule),
            count,
            mode,
        })
    }

    /// The candidate list of `view`, nearest first (empty for an unknown index).
    pub fn candidates(&self, view: usize) -> &[usize] {
        self.candidates.get(view).map_or(&[], |c| c.as_slice())
    }

    /// The source views of `view` for one iteration: min(N, #candidates) distinct indices;
    /// empty when the view has no neighbours (the multi-view losses are then skipped).
    pub fn select(&self, view: usize, rng: &mut Rng) -> Vec<usize> {
        let cands = self.candidates(view);
        match self.mode {
            SourceSelection::TopN => cands.iter().take(self.count).copied().collect(),
            SourceSelection::RandomN => rng
                .choose_distinct(cands.len(), self.count)
                .into_iter()
                .map(|k| cands[k])
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gs_core::Intrinsics;
    use gs_core::glam::DVec3;

    fn ring(n: usize) -> Vec<Camera> {
        gs_core::scene::camera_ring(n)
    }

    #[test]
    fn top_and_random_selection() {
        let cams = ring(24);
        let refs: Vec<&Camera> = cams.iter().collect();
        let top =
            SourceViewSelector::new(&refs, &NeighbourRule::default(), 3, SourceSelection::TopN)
                .unwrap();
        let mut rng = Rng::new(1);
        let s = top.select(0, &mut rng);
        assert_eq!(s.len(), 3);
        assert_eq!(&s, &top.candidates(0)[..3]);
        let rnd = SourceViewSelector::new(
            &refs,
            &NeighbourRule::default(),
            3,
            SourceSelection::RandomN,
        )
        .unwrap();
        let a = rnd.select(5, &mut Rng::new(9));
        assert_eq!(a, rnd.select(5, &mut Rng::new(9)), "seeded");
        assert_eq!(a.len(), 3);
        assert!(a.iter().all(|x| rnd.candidates(5).contains(x)));
        let mut sorted = a.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), 3);
    }

    #[test]
    fn views_without_neighbours_get_none() {
        // Two cameras facing opposite directions: no candidates.
        let k = Intrinsics::new(60.0, 60.0, 32.0, 24.0);
        let a =
            Camera::look_at(64, 48, k, DVec3::new(0.0, -3.0, 0.0), DVec3::ZERO, DVec3::Z).unwrap();
        let b =
            Camera::look_at(64, 48, k, DVec3::new(0.0, 3.0, 0.0), DVec3::ZERO, DVec3::Z).unwrap();
        let sel = SourceViewSelector::new(
            &[&a, &b],
            &NeighbourRule::default(),
            3,
            SourceSelection::RandomN,
        )
        .unwrap();
        assert!(sel.select(0, &mut Rng::new(0)).is_empty());
        assert!(sel.select(7, &mut Rng::new(0)).is_empty());
        assert!(
            SourceViewSelector::new(&[&a], &NeighbourRule::default(), 0, SourceSelection::TopN)
                .is_err()
        );
    }
}
