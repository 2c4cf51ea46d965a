//! Partitioned training for vagsl (docs/architecture.md §Partitioned training): a capture too
//! large for one machine is split on its ground plane into blocks with overlapping views, each
//! block is an ordinary scene folder that `vagsl train` trains as its own job (a shell loop,
//! a Slurm job array, a Kubernetes Indexed Job), and the trained blocks merge into one run of
//! the whole scene.
//!
//! - [`partition()`]: the plan ([`Plan`]) and the block folders.
//! - [`runners`]: the block script and the scheduler files.
//! - [`merge()`]: the checked, cropped union of the blocks' models as a run.
//! - [`BlockPieces`]: the merged run's blocks as the pieces its mesh is fused in.
//!
//! ```no_run
//! use gs_partition::{BlockCount, PartitionOptions, partition};
//! use gs_run::SceneSource;
//! let source = SceneSource { path: Some("street".into()), resolution_factor: None, width: None, eval: true };
//! // The settings of `vagsl train` arguments (the CLI parses them with train's own parser).
//! let config_of = |args: &[String]| -> Result<gs_train::TrainConfig, String> {
//!     let c = gs_train::TrainConfig::preset(gs_train::Preset::Fast);
//!     let mut c = match args.iter().position(|a| a == "--iterations") {
//!         Some(i) => c.scaled(args[i + 1].parse().map_err(|_| "bad --iterations".to_string())?),
//!         None => c,
//!     };
//!     if let Some(i) = args.iter().position(|a| a == "--set") {
//!         c = c.with_assignment(&args[i + 1]).map_err(|e| e.to_string())?;
//!     }
//!     Ok(c)
//! };
//! let opts = PartitionOptions {
//!     count: BlockCount::Exactly(4),
//!     margin: 0.2,
//!     visibility: 0.25,
//!     train_args: vec!["--preset".into(), "fast".into()],
//!     share_iterations: true,
//!     grow_in_region: true,
//!     config_of: &config_of,
//! };
//! let plan = partition(&source, "street-plan".as_ref(), &opts, &mut |line| eprintln!("{line}"))?;
//! println!("{} blocks", plan.blocks.len());
//! # Ok::<(), gs_partition::PartitionError>(())
//! ```

mod assign;
mod block_folder;
mod capture;
mod error;
mod ground;
mod merge;
mod mesh_blocks;
mod partition;
mod plan;
mod regions;
pub mod runners;

pub use assign::{Members, assign, visible_points};
pub use error::{PartitionError, Result};
pub use ground::GroundFrame;
pub use merge::{BlockSummary, MergeReport, Merged, merge, write_merged};
pub use mesh_blocks::BlockPieces;
pub use partition::{BlockCount, ConfigOf, MAX_BLOCKS, MIN_BLOCK_VIEWS, PartitionOptions, block_train_args, partition, REGION_KEY};
pub use plan::{Block, PLAN_FILE, PLAN_VERSION, Plan};
pub use regions::{Rect, Region, core_regions, grid_shape, weighted_cuts};
