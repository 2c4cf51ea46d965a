//! `PLAN/plan.json`: what `vagsl partition` decided and `vagsl merge` relies on
//! (docs/architecture.md §Partitioned training) — the scene, the ground frame, every block's
//! core region, grown region, views, scene fingerprint and memory estimate, and the training
//! arguments every block runs with. Read back with every field checked, so a hand-edited or
//! damaged plan is refused naming the block and the problem.

use crate::error::{Context, Result};
use crate::ground::GroundFrame;
use crate::regions::{Rect, Region};
use gs_run::{SceneFingerprint, SceneSource};
use gs_train::TrainConfig;
use serde::{Deserialize, Serialize};
use std::path::{Component, Path, PathBuf};

/// The plan file inside a plan folder.
pub const PLAN_FILE: &str = "plan.json";

/// The version of the plan format this build writes and reads.
pub const PLAN_VERSION: u32 = 1;

/// A partition of one scene into blocks.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Plan {
    /// Format version ([`PLAN_VERSION`]).
    pub version: u32,
    /// The scene partitioned (its folder absolute), how it is loaded, and whether its held-out
    /// views are kept out of every block (`eval`).
    pub scene: SceneSource,
    /// The whole scene's held-out views (with `eval`): in no block, scored after the merge.
    pub held_out: Vec<String>,
    /// The ground frame the regions are drawn in.
    pub frame: GroundFrame,
    /// Each core grows by this fraction of its size on every bounded side.
    pub margin: f64,
    /// A view joins a block when this fraction of the sparse points it sees lie in the block's
    /// grown region (or when its camera stands there).
    pub visibility: f64,
    /// Arguments every block's `vagsl train` gets after its scene and output folder (with its
    /// own `--iterations`, [`crate::block_train_args`]).
    pub train_args: Vec<String>,
    /// The settings of these arguments for the whole scene: the merged run's.
    pub train: TrainConfig,
    /// The blocks, in index order.
    pub blocks: Vec<Block>,
}

/// One block of a plan.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Block {
    /// Position in the plan (0-based; the Slurm array index and Kubernetes completion index).
    pub index: usize,
    /// The block's scene folder, relative to the plan folder (`blocks/NN`).
    pub scene: PathBuf,
    /// The block's run folder, relative to the plan folder (`runs/NN`).
    pub run: PathBuf,
    /// The region whose Gaussians the merge keeps from this block.
    pub core: Region,
    /// The core grown by the margin: where the block's views look and its points lie.
    pub grown: Rect,
    /// Names of the block's views (all train; none of the scene's held-out views).
    pub views: Vec<String>,
    /// Number of sparse points in the block's scene.
    pub points: usize,
    /// The block scene's fingerprint as `train` records it, so the merge knows the block run
    /// was trained on this block's scene.
    pub fingerprint: SceneFingerprint,
    /// Pixels of the block's largest view as `train` loads it (for the job time limit).
    pub largest_view_pixels: u64,
    /// The training memory estimate of the block, bytes (what `train` checks before it starts).
    pub memory_bytes: u64,
    /// The estimate's parts in words.
    pub memory: String,
    /// The settings the block trains with (the plan's arguments at its iterations): the merge
    /// refuses a block run trained with others.
    pub train: TrainConfig,
}

impl Block {
    /// The block's name, its index with two digits (`07`).
    pub fn name(&self) -> String {
        format!("{:02}", self.index)
    }
}

impl Plan {
    /// Reads and checks `DIR/plan.json`.
    pub fn read(dir: &Path) -> Result<Self> {
        let path = dir.join(PLAN_FILE);
        let bytes = gs_io::read_capped(&path, gs_io::JSON_CAP, "a partition plan")
            .with_context(|| format!("{}: cannot read the plan (is {} a folder made by `vagsl partition`?)", path.display(), dir.display()))?;
        let plan: Plan = serde_json::from_slice(&bytes).map_err(|e| {
            crate::PartitionError::Refused(format!("{}: not a vagsl partition plan: {}", path.display(), gs_io::json_error_words(&bytes, &e)))
        })?;
        plan.validate().map_err(|why| crate::PartitionError::Refused(format!("{}: {why}", path.display())))?;
        Ok(plan)
    }

    /// Writes the plan to `DIR/plan.json` atomically.
    pub fn write(&self, dir: &Path) -> Result<()> {
        self.validate().map_err(|why| crate::PartitionError::Refused(format!("refusing to write a plan that {why}")))?;
        gs_run::write_json(&dir.join(PLAN_FILE), self)?;
        Ok(())
    }

    /// Checks everything a reader relies on, in words.
    pub fn validate(&self) -> std::result::Result<(), String> {
        if self.version != PLAN_VERSION {
            return Err(format!("plan format version {} (this vagsl reads version {PLAN_VERSION}); partition the scene again", self.version));
        }
        if self.blocks.is_empty() {
            return Err("the plan has no blocks".into());
        }
        self.frame.validate()?;
        if !(self.margin.is_finite() && (0.0..=1.0).contains(&self.margin)) {
            return Err(format!("margin {} is not a fraction from 0 to 1", self.margin));
        }
        if !(self.visibility.is_finite() && self.visibility > 0.0 && self.visibility <= 1.0) {
            return Err(format!("visibility {} is not a fraction above 0 and at most 1", self.visibility));
        }
        for (i, b) in self.blocks.iter().enumerate() {
            let bad = |why: String| format!("block {i}: {why}");
            if b.index != i {
                return Err(bad(format!("its index is {} (blocks must be listed in order from 0)", b.index)));
            }
            for (what, p) in [("scene", &b.scene), ("run", &b.run)] {
                if !is_inside_relative(p) {
                    return Err(bad(format!("its {what} folder '{}' is not a relative path inside the plan folder", p.display())));
                }
            }
            b.core.validate().map_err(|w| bad(format!("core region: {w}")))?;
            if !(b.grown.min.iter().chain(&b.grown.max).all(|x| x.is_finite()) && (0..2).all(|a| b.grown.min[a] <= b.grown.max[a])) {
                return Err(bad("its grown region is not a finite rectangle".into()));
            }
            if b.views.is_empty() {
                return Err(bad("it has no views".into()));
            }
            if let Some(n) = b.views.iter().find(|n| self.held_out.contains(n)) {
                return Err(bad(format!("it trains on '{n}', a held-out view of the scene")));
            }
        }
        Ok(())
    }
}

/// Whether `p` is a relative path that stays inside its base (no `..`, no root).
fn is_inside_relative(p: &Path) -> bool {
    !p.as_os_str().is_empty() && p.components().all(|c| matches!(c, Component::Normal(_) | Component::CurDir))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths_must_stay_inside() {
        assert!(is_inside_relative(Path::new("blocks/00")));
        assert!(!is_inside_relative(Path::new("../x")));
        assert!(!is_inside_relative(Path::new("/etc")));
        assert!(!is_inside_relative(Path::new("blocks/../../x")));
        assert!(!is_inside_relative(Path::new("")));
    }
}
