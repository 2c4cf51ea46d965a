//! One module per subcommand.

pub mod convert;
pub mod eval_images;
pub mod eval_mesh;
pub mod info;
pub mod mesh;
pub mod render;
pub mod tradeoff;
pub mod train;
