//! The report page of a trained run (issue #20): one offline HTML page, `RUN/report.html`,
//! with an interactive WebGL2 viewer of the splats (depth-sorted alpha blending, SH up to
//! degree 3, the exact pinhole cameras of the scene) and of the mesh, the training and
//! held-out views side by side (photo, render, normal and depth maps with their scores), the
//! training curves and the mesh and tradeoff results when present.
//!
//! The crate knows nothing about training: its caller (the `vagsl view` command) renders the
//! views and hands over images, metrics and the model; [`ReportWriter`] writes the images to
//! `RUN/report/` and the page with its data (`RUN/report/data.js`, loaded by a `<script>` tag
//! so that the page also works from `file://`, where browsers refuse `fetch`).
//!
//! Why our own renderer rather than an npm splat library: the page must show a scene view
//! exactly as `vagsl render` does (the test compares them pixel by pixel), so it needs our
//! camera model (fx, fy, cx, cy of each photo), the run's projection (its low-pass filter and
//! opacity compensation, the 1.3·fov Jacobian clamp, 1/255 alpha cut, 0.99 alpha cap) and our SH convention; the web viewers
//! take a field of view and their own conventions. The renderer is ~300 lines of JavaScript
//! and GLSL with no dependency, so nothing is downloaded at build or view time.

mod colormap;
mod data;
mod error;
mod writer;

pub use colormap::depth_colormap;
pub use data::{CameraData, MeshData, Projection, SplatData};
pub use error::{ReportError, Result};
pub use writer::{Curves, PageData, ReportWriter, ViewScores, escape_html};
