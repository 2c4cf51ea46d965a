//! [`ReportWriter`]: collects a run's views and results and writes `RUN/report.html` with its
//! folder `RUN/report/` (view images and `data.js`). The folder is assembled under a temporary
//! name and swapped in whole, and the page is written last, atomically: an interrupted `view`
//! leaves the previous report intact, never half of a new one.

use crate::colormap::depth_colormap;
use crate::data::{CameraData, MeshData, SplatData};
use crate::error::{ReportError, Result};
use gs_core::{Camera, Image};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The page template and its assets, embedded in the binary (no network at view time).
const TEMPLATE: &str = include_str!("../assets/report.html");
const STYLE: &str = include_str!("../assets/style.css");
const VIEWER: &str = include_str!("../assets/viewer.js");
const PAGE: &str = include_str!("../assets/page.js");

/// JPEG quality of the view images (visually lossless at this size).
const JPEG_QUALITY: u8 = 92;

/// Image scores of one view (docs/method.md §Metrics).
#[derive(Debug, Clone, Serialize)]
pub struct ViewScores {
    /// PSNR, dB.
    pub psnr: f64,
    /// SSIM.
    pub ssim: f64,
    /// LPIPS-alex, when computed.
    pub lpips: Option<f64>,
    /// A note shown under the scores in words (e.g. a veil in front of the camera), if any.
    pub note: Option<String>,
}

/// Training curves: the lines of `RUN/metrics.jsonl` as JSON objects (iteration, seconds,
/// loss terms, Gaussians, held-out PSNR).
pub type Curves = Vec<serde_json::Value>;

/// One view of the page: its camera, its four images (paths relative to the page) and scores.
#[derive(Debug, Serialize)]
struct ViewEntry {
    camera: CameraData,
    photo: String,
    render: String,
    normal: String,
    depth: String,
    depth_range: Option<(f32, f32)>,
    scores: Option<ViewScores>,
}

/// Everything the page shows besides the views.
#[derive(Debug, Serialize)]
pub struct PageData {
    /// Page title (empty: "vagsl report: " and the run folder's name).
    pub title: String,
    /// The run's facts as (label, value) pairs in words and units, shown at the top.
    pub facts: Vec<(String, String)>,
    /// The splats.
    pub splats: SplatData,
    /// The mesh, when the run has one.
    pub mesh: Option<MeshData>,
    /// The rasterizer's background colour (the viewer clears to it).
    pub background: [f32; 3],
    /// Training curves.
    pub curves: Curves,
    /// Mesh metrics (`eval-mesh`'s JSON) when present.
    pub mesh_metrics: Option<serde_json::Value>,
    /// The tradeoff plot (SVG text) when present.
    pub tradeoff_svg: Option<String>,
}

/// Writes a report page into a run folder: [`ReportWriter::add_view`] for every view, then
/// [`ReportWriter::finish`].
pub struct ReportWriter {
    run: PathBuf,
    staging: PathBuf,
    views: Vec<ViewEntry>,
}

fn create_dir(path: &Path) -> Result<()> {
    std::fs::create_dir_all(path).map_err(|source| ReportError::Folder { path: path.to_path_buf(), source })
}

impl ReportWriter {
    /// Starts a report in `run` (the folder must exist); nothing visible changes until
    /// [`finish`](Self::finish).
    pub fn new(run: &Path) -> Result<Self> {
        let staging = run.join(format!(".report.{}.tmp", std::process::id()));
        // Folders of `view`s killed mid-way (their process gone) would otherwise stay forever.
        gs_io::remove_stale_temps(run, "report");
        if staging.exists() {
            std::fs::remove_dir_all(&staging).map_err(|source| ReportError::Folder { path: staging.clone(), source })?;
        }
        create_dir(&staging.join("views"))?;
        Ok(Self { run: run.to_path_buf(), staging, views: Vec::new() })
    }

    /// Adds a view: the photo, the render, the world-normal map (encoded (n + 1)/2) and the
    /// plane depth (one channel, 0 = none) at the view's resolution, and its scores.
    #[allow(clippy::too_many_arguments)]
    pub fn add_view(
        &mut self,
        name: &str,
        split: &'static str,
        camera: &Camera,
        photo: &Image,
        render: &Image,
        normal: &Image,
        depth: &Image,
        scores: Option<ViewScores>,
    ) -> Result<()> {
        let i = self.views.len();
        let file = |kind: &str| format!("report/views/{i:04}_{kind}.jpg");
        let (depth_rgb, depth_range) = depth_colormap(depth);
        for (kind, img) in [("photo", photo), ("render", render), ("normal", normal), ("depth", &depth_rgb)] {
            gs_io::write_jpeg(&self.staging.join(format!("views/{i:04}_{kind}.jpg")), img, JPEG_QUALITY)?;
        }
        self.views.push(ViewEntry {
            camera: CameraData::new(name, split, camera),
            photo: file("photo"),
            render: file("render"),
            normal: file("normal"),
            depth: file("depth"),
            depth_range,
            scores,
        });
        Ok(())
    }

    /// Writes `report/data.js`, swaps the new `report/` folder in and writes `report.html`
    /// (atomically, last). Returns the page's path.
    pub fn finish(self, mut page: PageData) -> Result<PathBuf> {
        if page.title.is_empty() {
            page.title = page_title(&self.run);
        }
        if self.views.is_empty() {
            return Err(ReportError::Invalid("a report needs at least one view".into()));
        }
        let data = serde_json::json!({ "page": page, "views": self.views });
        let js = format!("window.VAGSL_DATA = {};\n", serde_json::to_string(&data).map_err(|e| ReportError::Invalid(e.to_string()))?);
        gs_io::write_atomic(&self.staging.join("data.js"), |w| w.write_all(js.as_bytes()))?;
        let folder = self.run.join("report");
        if folder.exists() {
            std::fs::remove_dir_all(&folder).map_err(|source| ReportError::Folder { path: folder.clone(), source })?;
        }
        std::fs::rename(&self.staging, &folder).map_err(|source| ReportError::Folder { path: folder.clone(), source })?;
        let html = TEMPLATE
            .replace("/*STYLE*/", STYLE)
            .replace("/*VIEWER*/", VIEWER)
            .replace("/*PAGE*/", PAGE)
            .replace("<!--TITLE-->", &escape_html(&page.title));
        let path = self.run.join("report.html");
        gs_io::write_atomic(&path, |w| w.write_all(html.as_bytes()))?;
        Ok(path)
    }
}

impl Drop for ReportWriter {
    /// An abandoned report (an error before `finish`) leaves no staging folder behind.
    fn drop(&mut self) {
        if self.staging.exists() {
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
}

fn page_title(run: &Path) -> String {
    let name = run.canonicalize().ok().and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()));
    format!("vagsl report: {}", name.unwrap_or_else(|| run.display().to_string()))
}

/// `s` as HTML/SVG text: `&`, `<` and `>` escaped.
pub fn escape_html(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

