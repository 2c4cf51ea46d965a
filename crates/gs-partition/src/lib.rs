//! Partitioned training for vagsl (docs/architecture.md §Partitioned training): a capture too
//! large for one machine is split on its ground plane into blocks with overlapping views, each
//! block is an ordinary scene folder that `vagsl train` trains as its own job (a shell loop,
//! a Slurm job array, a Kubernetes Indexed Job), and the trained blocks merge into one run of
//! the whole scene.
//!
//! - [`partition()`]: the plan ([`Plan`]) and the block folders.
//! - [`runners`]: the block script and the scheduler files.
//! - [`merge()`]: the checked, cropped union of the blocks' models as a run.
//!
//! ```no_run
//! use gs_partition::{BlockCount, PartitionOptions, partition};
//! use gs_run::SceneSource;
//! let source = SceneSource { path: Some("street".into()), resolution_factor: None, width: None, eval: true };
//! let config_of = |iterations: Option<u64>| {
//!     let c = gs_train::TrainConfig::preset(gs_train::Preset::Fast);
//!     Ok(iterations.map_or(c.clone(), |n| c.scaled(n)))
//! };
//! let opts = PartitionOptions {
//!     count: BlockCount::Exactly(4),
//!     margin: 0.2,
//!     visibility: 0.25,
//!     train_args: vec!["--preset".into(), "fast".into()],
//!     share_iterations: true,
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
mod partition;
mod plan;
mod regions;
pub mod runners;

pub use assign::{Members, assign, visible_points};
pub use error::{PartitionError, Result};
pub use ground::GroundFrame;
pub use merge::{BlockSummary, MergeReport, Merged, merge, write_merged};
pub use partition::{BlockCount, ConfigOf, MAX_BLOCKS, MIN_BLOCK_VIEWS, PartitionOptions, block_train_args, partition};
pub use plan::{Block, PLAN_FILE, PLAN_VERSION, Plan};
pub use regions::{Rect, Region, core_regions, grid_shape, weighted_cuts};
