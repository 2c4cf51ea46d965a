//! Meshing a merged run block by block (docs/architecture.md §Partitioned training, step 8):
//! the blocks' core regions, which the merge records in the run's `report.json`, are the pieces
//! of a fusion piece by piece ([`gs_train::fuse_mesh_in_pieces`]), so the mesh of a scene too
//! large for one TSDF volume needs only the largest block's.

use crate::error::{Context, Result, refuse};
use crate::ground::GroundFrame;
use crate::regions::Region;
use glam::DVec3;
use gs_train::FusionPieces;
use serde::Deserialize;
use std::path::Path;

/// The blocks of a merged run as the pieces of a fusion: each point belongs to the block whose
/// core region holds its ground coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockPieces {
    frame: GroundFrame,
    cores: Vec<Region>,
}

/// The fields of a merged run's `report.json` that the pieces come from.
#[derive(Deserialize)]
struct MergedFields {
    frame: GroundFrame,
    blocks: Vec<CoreField>,
}

#[derive(Deserialize)]
struct CoreField {
    core: Region,
}

impl BlockPieces {
    /// The blocks of the merged run in `dir`, from its `report.json`; `None` for a run that is
    /// not a merge (or a merge written before the report recorded its regions).
    pub fn of_merged_run(dir: &Path) -> Result<Option<Self>> {
        let path = dir.join("report.json");
        let bytes = gs_io::read_capped(&path, gs_io::JSON_CAP, "a run report").with_context(|| format!("{}: cannot read the run's report", path.display()))?;
        let value: serde_json::Value = serde_json::from_slice(&bytes).with_context(|| format!("{}: not a JSON run report", path.display()))?;
        if value.get("frame").is_none() || value.get("plan").is_none() {
            return Ok(None);
        }
        let fields: MergedFields = serde_json::from_value(value).with_context(|| format!("{}: a merged run's report without readable block regions", path.display()))?;
        let pieces = Self { frame: fields.frame, cores: fields.blocks.into_iter().map(|b| b.core).collect() };
        if let Err(why) = pieces.frame.validate() {
            refuse!("{}: the merged run's ground frame {why}", path.display());
        }
        for (k, core) in pieces.cores.iter().enumerate() {
            if let Err(why) = core.validate() {
                refuse!("{}: block {k:02}'s core region: {why}", path.display());
            }
        }
        if pieces.cores.is_empty() {
            refuse!("{}: a merged run's report that lists no blocks", path.display());
        }
        Ok(Some(pieces))
    }
}

impl FusionPieces for BlockPieces {
    fn count(&self) -> usize {
        self.cores.len()
    }

    /// The first block whose core holds `p` (cores tile the plane, so there is one; a point
    /// outside every core of a damaged report goes to the last block rather than nowhere).
    fn owner(&self, p: DVec3) -> usize {
        let c = self.frame.coords(p);
        self.cores.iter().position(|r| r.contains(c)).unwrap_or(self.cores.len() - 1)
    }

    /// The core grown by `reach` on its bounded sides (a superset of the points within `reach`).
    fn near(&self, piece: usize, p: DVec3, reach: f64) -> bool {
        let c = self.frame.coords(p);
        let r = &self.cores[piece];
        let inside = |x: f64, [lo, hi]: [Option<f64>; 2]| lo.is_none_or(|lo| x >= lo - reach) && hi.is_none_or(|hi| x < hi + reach);
        inside(c[0], r.u) && inside(c[1], r.v) || self.owner(p) == piece
    }

    fn name(&self, piece: usize) -> String {
        format!("block {piece:02}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn strips() -> BlockPieces {
        let frame = GroundFrame { origin: [0.0; 3], u: [1.0, 0.0, 0.0], v: [0.0, 0.0, 1.0], up: [0.0, -1.0, 0.0] };
        let cores = vec![
            Region { u: [None, Some(-1.0)], v: [None, None] },
            Region { u: [Some(-1.0), Some(2.0)], v: [None, None] },
            Region { u: [Some(2.0), None], v: [None, None] },
        ];
        BlockPieces { frame, cores }
    }

    #[test]
    fn every_point_has_one_owner_and_is_near_it() {
        let b = strips();
        for x in [-5.0, -1.0 - 1e-9, -1.0, 0.5, 2.0 - 1e-9, 2.0, 40.0] {
            let p = DVec3::new(x, 3.0, -7.0);
            let k = b.owner(p);
            assert_eq!(k, usize::from(x >= -1.0) + usize::from(x >= 2.0), "{x}");
            assert!(b.near(k, p, 0.0));
        }
        assert!(b.near(0, DVec3::new(-0.8, 0.0, 0.0), 0.25) && !b.near(0, DVec3::new(-0.7, 0.0, 0.0), 0.25));
        assert!(b.near(2, DVec3::new(1.8, 0.0, 0.0), 0.25) && !b.near(2, DVec3::new(1.7, 0.0, 0.0), 0.25));
    }
}
