//! `vagsl view`: the report page in a real headless Chromium (Debian's `chromium`). The viewer
//! at a scene camera must match `vagsl render` of that view (PSNR ≥ 20 dB at the same size),
//! — held here to 40 dB — for a training and a held-out view, with no script error; the mesh toggle draws the mesh;
//! `--serve` serves the page and nothing else. Without a Chromium the browser checks are
//! skipped with a line saying so (CI installs it).
//!
//! `VAGSL_UPDATE_DOCS=1` also writes the page's screenshot for the README (docs/report.png).

use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;

fn vagsl(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vagsl")).args(args).output().expect("run vagsl");
    (out.status.success(), String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// One trained run (built-in scene, held-out views, SH degree 3 reached, a mesh, mesh scores
/// and the report page), shared by the tests of this file.
fn run_dir() -> &'static Path {
    static RUN: OnceLock<PathBuf> = OnceLock::new();
    RUN.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap().keep();
        let out = dir.join("run");
        let o = out.to_str().unwrap();
        // The built-in scene's own ground-truth mesh (its objects), as gs-testdata writes it.
        let scene = gs_testdata::builtin::scene_dir(Path::new(env!("CARGO_TARGET_TMPDIR")), &gs_testdata::builtin::small());
        let gt = scene.join("gt_mesh.ply");
        let gt = gt.to_str().unwrap();
        let (ok, stdout, err) = vagsl(&["train", "-o", o, "--iterations", "300", "--preset", "fast", "--eval", "--quiet", "--track-gt", gt]);
        assert!(ok, "{err}");
        assert!(stdout.contains(&format!("vagsl view {o}")), "the summary names the next command: {stdout}");
        let (ok, _, err) = vagsl(&["mesh", o]);
        assert!(ok, "{err}");
        let mesh = out.join("mesh.ply");
        let (ok, _, err) = vagsl(&["eval-mesh", "--pred", mesh.to_str().unwrap(), "--gt", mesh.to_str().unwrap(), "--samples", "2000"]);
        assert!(ok, "{err}");
        let (ok, stdout, err) = vagsl(&["view", o]);
        assert!(ok, "{err}");
        assert!(stdout.contains("report.html"), "{stdout}");
        let (ok, _, err) = vagsl(&["render", o, "--split", "all"]);
        assert!(ok, "{err}");
        out
    })
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

#[test]
fn the_page_holds_everything_it_shows_and_needs_no_network() {
    let run = run_dir();
    let html = std::fs::read_to_string(run.join("report.html")).unwrap();
    assert!(html.contains("<canvas id=\"viewer\""));
    assert!(!html.contains("src=\"http") && !html.contains("<link"), "the page loads nothing from the network");
    let data = std::fs::read_to_string(run.join("report/data.js")).unwrap();
    let value: serde_json::Value = serde_json::from_str(data.trim().strip_prefix("window.VAGSL_DATA = ").unwrap().trim_end_matches(';')).unwrap();
    let views = value["views"].as_array().unwrap();
    assert_eq!(views.len(), 32, "every view of the built-in scene");
    assert_eq!(views.iter().filter(|v| v["camera"]["split"] == "test").count(), 4);
    for v in views {
        for k in ["photo", "render", "normal", "depth"] {
            assert!(run.join(v[k].as_str().unwrap()).is_file(), "{k} image of {}", v["camera"]["name"]);
        }
        assert!(v["scores"]["psnr"].as_f64().unwrap() > 10.0 && v["scores"]["lpips"].as_f64().is_some());
    }
    let page = &value["page"];
    let report = json(&run.join("report.json"));
    assert_eq!(page["splats"]["count"], report["gaussians"]);
    assert_eq!(page["splats"]["sh_degree"], 3);
    assert!(page["mesh"]["triangles"].as_u64().unwrap() > 100);
    let m = &page["mesh_metrics"];
    assert!(m["chamfer"].as_f64().is_some_and(|c| c.is_finite()) && m["f1"].as_f64().is_some(), "{m}");
    assert!(m["ground_truth"].as_str().unwrap().ends_with("mesh.ply"));
    // Curves: loss every 10 iterations, held-out PSNR 10 times and at the end.
    let curves = page["curves"].as_array().unwrap();
    assert_eq!(curves.iter().filter(|c| c.get("loss").is_some()).count(), 30);
    let held: Vec<_> = curves.iter().filter_map(|c| c.get("heldout_psnr")).collect();
    assert_eq!(held.len(), 10);
    assert_eq!(curves.iter().filter(|c| c["chamfer"].as_f64().is_some_and(f64::is_finite)).count(), 10, "the mesh curve");
    let seconds: Vec<f64> = curves.iter().map(|c| c["seconds"].as_f64().unwrap()).collect();
    assert!(seconds.windows(2).all(|w| w[1] >= w[0]), "time only moves forward");
    assert!(*seconds.last().unwrap() <= report["train_seconds"].as_f64().unwrap() + 1e-6);
}

/// Debian's Chromium, or the one named by `CHROMIUM`.
fn chromium() -> Option<PathBuf> {
    let candidates = std::env::var_os("CHROMIUM").map(PathBuf::from).into_iter().chain(["chromium", "chromium-browser", "google-chrome"].map(PathBuf::from));
    candidates.into_iter().find(|c| Command::new(c).arg("--version").output().is_ok_and(|o| o.status.success()))
}

/// Runs headless Chromium on `url` at `w`×`h` with `what` (`--screenshot=…` or `--dump-dom`);
/// returns stdout. Every console message of the page (which logs nothing when all is well:
/// script errors, WebGL warnings, resources that failed to load) fails the test.
fn browse(chrome: &Path, url: &str, w: u32, h: u32, what: &str) -> String {
    browse_with(chrome, url, w, h, what, &[])
}

/// [`browse`] with `extra` Chromium flags.
fn browse_with(chrome: &Path, url: &str, w: u32, h: u32, what: &str, extra: &[&str]) -> String {
    let profile = tempfile::tempdir().unwrap();
    let out = Command::new(chrome)
        .args([
            "--headless",
            "--no-sandbox",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--hide-scrollbars",
            "--no-first-run",
            "--virtual-time-budget=30000",
            "--enable-logging=stderr",
            "--v=0",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .arg(format!("--window-size={w},{h}"))
        .args(extra)
        .arg(what)
        .arg(url)
        .output()
        .expect("run chromium");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "chromium failed: {stderr}");
    let console: Vec<&str> = stderr.lines().filter(|l| l.contains(":CONSOLE")).collect();
    assert!(console.is_empty(), "console messages at {url}:\n{}", console.join("\n"));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The page's own record of itself (`<body data-status>`): ready, script errors, the view.
fn page_status(dom: &str) -> serde_json::Value {
    let start = dom.find("data-status=\"").expect("the page reports its status") + "data-status=\"".len();
    let raw = &dom[start..start + dom[start..].find('"').unwrap()];
    serde_json::from_str(&raw.replace("&quot;", "\"").replace("&amp;", "&")).unwrap()
}

fn psnr(a: &image::RgbImage, b: &image::RgbImage) -> f64 {
    assert_eq!(a.dimensions(), b.dimensions());
    let se: f64 = a.as_raw().iter().zip(b.as_raw()).map(|(x, y)| (*x as f64 - *y as f64).powi(2)).sum();
    let mse = se / a.as_raw().len() as f64 / 255.0 / 255.0;
    -10.0 * mse.max(1e-12).log10()
}

#[test]
fn the_viewer_at_a_scene_camera_matches_vagsl_render() {
    let Some(chrome) = chromium() else {
        // `.ci/run` installs Chromium, so in CI its absence is a failure, not a skip.
        gs_testdata::skip_or_fail!(
            "no Chromium found: the report page was not tested in a browser",
            "install Debian's `chromium`, or set CHROMIUM=PATH"
        );
        return;
    };
    let run = run_dir();
    let page = run.join("report.html");
    for name in ["0008.png", "0013.png"] {
        let split = if json(&run.join("config.json"))["test_views"].as_array().unwrap().iter().any(|v| v == name) { "held-out" } else { "training" };
        let url = format!("file://{}#view={name}&viewer", page.display());
        let expected = image::open(run.join("renders/all").join(name)).unwrap().to_rgb8();
        let (w, h) = expected.dimensions();
        let dom = browse(&chrome, &url, w, h, "--dump-dom");
        let status = page_status(&dom);
        assert_eq!(status["ready"], true, "{status}");
        assert_eq!(status["errors"].as_array().unwrap().len(), 0, "script errors: {status}");
        assert_eq!(status["view"], name);
        let shot_path = run.join(format!("shot_{name}"));
        browse(&chrome, &url, w, h, &format!("--screenshot={}", shot_path.display()));
        let shot = image::open(&shot_path).unwrap().to_rgb8();
        let p = psnr(&shot, &expected);
        eprintln!("viewer vs vagsl render at {split} view {name} ({w}×{h}): PSNR {p:.2} dB");
        // The issue asks for 20 dB; the viewer computes what the rasterizer computes, so it is
        // held to 40 (measured: 60 dB; a depth-order bug gave 34).
        assert!(p >= 40.0, "{split} view {name}: the viewer differs from vagsl render (PSNR {p:.2} dB)");
    }
    // The mesh toggle: the fused mesh, shaded, fills the view's object region.
    let url = format!("file://{}#view=0008.png&viewer&mode=mesh", page.display());
    let shot_path = run.join("shot_mesh.png");
    browse(&chrome, &url, 200, 150, &format!("--screenshot={}", shot_path.display()));
    let shot = image::open(&shot_path).unwrap().to_rgb8();
    let lit = shot.pixels().filter(|p| p[0] > 20).count();
    assert!(lit > shot.len() / 3 / 4, "only {lit} shaded pixels in the mesh view");
    // The whole page, as a person sees it (the README's screenshot).
    let full = run.join("page.png");
    let url = format!("file://{}", page.display());
    browse(&chrome, &url, 1280, 1500, &format!("--screenshot={}", full.display()));
    let dom = browse(&chrome, &url, 1280, 1500, "--dump-dom");
    for title in ["Training loss", "Gaussians", "Held-out PSNR (dB)", "Mesh Chamfer vs ground truth"] {
        assert!(dom.contains(&format!(">{title}</text>")), "the {title} plot is drawn");
    }
    let status = page_status(&dom);
    assert_eq!(status["errors"].as_array().unwrap().len(), 0, "script errors: {status}");
    // Without WebGL2 (Chromium's 3D APIs off) the page says why the viewer is missing and
    // still shows every view with its scores, the curves and the results.
    let dom = browse_with(&chrome, &url, 1280, 1500, "--dump-dom", &["--disable-3d-apis"]);
    assert!(dom.contains("class=\"error\">The viewer could not start: this browser offers no WebGL2"), "no WebGL2 message");
    let views = json(&run.join("config.json"))["test_views"].as_array().unwrap().len();
    assert_eq!(dom.matches("<tr class=\"test\">").count(), views, "the held-out views are listed without WebGL2");
    assert!(dom.contains(">Training loss</text>"), "the curves are drawn without WebGL2");
    if std::env::var_os("VAGSL_UPDATE_DOCS").is_some() {
        let docs = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/report.png"));
        std::fs::copy(&full, &docs).unwrap();
        eprintln!("wrote {}", docs.display());
    }
}

fn get(addr: &str, path: &str) -> (u16, Vec<u8>) {
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    write!(s, "GET {path} HTTP/1.0\r\nHost: {addr}\r\n\r\n").unwrap();
    let mut buf = Vec::new();
    s.read_to_end(&mut buf).unwrap();
    let head_end = buf.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
    let status: u16 = String::from_utf8_lossy(&buf[9..12]).parse().unwrap();
    (status, buf[head_end + 4..].to_vec())
}

#[test]
fn serve_gives_the_page_and_nothing_else() {
    // A copy of the run, so that this `view` does not rewrite the page the browser test reads.
    let copy = tempfile::tempdir().unwrap();
    let run = copy.path();
    for f in ["config.json", "point_cloud.ply", "report.json"] {
        std::fs::copy(run_dir().join(f), run.join(f)).unwrap();
    }
    let mut child = Command::new(env!("CARGO_BIN_EXE_vagsl"))
        .args(["view", run.to_str().unwrap(), "--serve", "--port", "0", "--no-lpips", "--backend", "cpu"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let url = lines
        .by_ref()
        .map_while(Result::ok)
        .find_map(|l| l.strip_prefix("serving ").map(|u| u.split_whitespace().next().unwrap().to_string()))
        .expect("a 'serving URL' line");
    let addr = url.trim_start_matches("http://").split('/').next().unwrap().to_string();
    assert!(addr.starts_with("127.0.0.1:"), "{url}");
    let (code, body) = get(&addr, "/report.html");
    assert_eq!(code, 200);
    assert!(String::from_utf8_lossy(&body).contains("<canvas id=\"viewer\""));
    assert_eq!(get(&addr, "/report/data.js").0, 200);
    assert_eq!(get(&addr, "/config.json").0, 404);
    assert_eq!(get(&addr, "/report/../config.json").0, 404);
    child.kill().unwrap();
    child.wait().unwrap();
}

#[test]
fn view_of_a_folder_without_a_run_names_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let (ok, _, err) = vagsl(&["view", dir.path().to_str().unwrap()]);
    assert!(!ok);
    assert!(err.contains("config.json") && err.contains("vagsl train"), "{err}");
    assert!(!dir.path().join("report.html").exists() && !dir.path().join("report").exists());
}
