//! `vagsl export` on a real (tiny) trained run of the built-in scene and its mesh: every format
//! is written, read back with gs-export's readers and, where one is installed, with an
//! independent reader (Python `plyfile` for the PLY outputs, `pygltflib` for .glb); bad input
//! gives clear errors and writes nothing. The quantisation bounds themselves are asserted on
//! real data in gs-export's tests.

use gs_export::{Format, read_gaussians, read_mesh, write_order};
use std::path::{Path, PathBuf};
use std::process::Command;

fn vagsl(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vagsl")).args(args).output().expect("run vagsl");
    (out.status.success(), String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// A 4-iteration CPU run of the built-in scene in `dir/run`, with a coarse mesh when `mesh`.
fn trained_run(dir: &Path, mesh: bool) -> PathBuf {
    let run = dir.join("run");
    let r = run.to_str().unwrap();
    let (ok, _, err) = vagsl(&["train", "-o", r, "--iterations", "4", "--backend", "cpu", "--quiet"]);
    assert!(ok, "{err}");
    if mesh {
        let (ok, _, err) = vagsl(&["mesh", r, "--backend", "cpu", "--voxel-size", "0.06"]);
        assert!(ok, "{err}");
    }
    run
}

/// Whether `python3` can import `module`; prints the skip line when it cannot.
fn python_has(module: &str) -> bool {
    let ok = Command::new("python3").args(["-c", &format!("import {module}")]).output().is_ok_and(|o| o.status.success());
    if !ok {
        // Straight to stderr: libtest captures println!/eprintln! of a passing test, and the
        // skip must be seen.
        use std::io::Write;
        let _ = writeln!(std::io::stderr(), "SKIPPED: python {module} not installed (pip install {module}): an independent reader check did not run");
    }
    ok
}

/// Runs a Python snippet with `args` as `sys.argv[1:]`, asserting it succeeds; returns stdout.
fn python(script: &str, args: &[&Path]) -> String {
    let out = Command::new("python3").arg("-c").arg(script).args(args).output().expect("run python3");
    assert!(out.status.success(), "python failed: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).trim().to_string()
}

#[test]
fn every_format_of_a_trained_run() {
    let dir = tempfile::tempdir().unwrap();
    let run = trained_run(dir.path(), true);
    let r = run.to_str().unwrap();
    let model = gs_io::read_gaussian_ply(&run.join("point_cloud.ply")).unwrap();
    let mesh = gs_io::read_mesh_ply(&run.join("mesh.ply")).unwrap();
    assert!(mesh.colors.is_some() && !mesh.triangles.is_empty());
    let out = |name: &str| dir.path().join(name);
    for (format, name, flag) in [
        (Format::Ply, "model.ply", true),
        (Format::Splat, "model.splat", false),
        (Format::Spz, "model.spz", false),
        (Format::CompressedPly, "model_compressed.ply", true),
        (Format::MeshPly, "mesh_out.ply", true),
        (Format::Obj, "mesh.obj", false),
        (Format::Glb, "mesh.glb", false),
    ] {
        let o = out(name);
        let mut args = vec!["export", r, "-o", o.to_str().unwrap()];
        if flag {
            args.extend(["--format", format.name()]);
        }
        let (ok, stdout, err) = vagsl(&args);
        assert!(ok, "{format}: {err}");
        assert!(stdout.contains(format.name()) && stdout.contains(name), "{stdout}");
        // The default preset trains with opacity compensation: spz records it, the other
        // Gaussian formats cannot and say so.
        if !format.is_mesh() {
            let recorded = format.records_antialiasing();
            assert_eq!(stdout.contains("antialiased"), recorded, "{format}: {stdout}");
            assert_eq!(err.contains("opacity compensation"), !recorded, "{format}: {err}");
        }
        if format == Format::Spz {
            let bytes = std::fs::read(&o).unwrap();
            assert!(gs_export::spz::decode_spz(&bytes, &o).unwrap().1, "spz's antialiased flag");
        }
        if format.is_mesh() {
            let back = read_mesh(format, &o).unwrap();
            assert_eq!(back.triangles.len(), mesh.triangles.len(), "{format}");
            if format != Format::Obj {
                assert_eq!(back, mesh, "{format}");
            }
            continue;
        }
        let back = read_gaussians(format, &o).unwrap();
        assert_eq!(back.len(), model.len(), "{format}");
        // Positions come back within the format's position quantisation (see gs-export).
        let extent = model.means.iter().flatten().fold(0f32, |m, v| m.max(v.abs()));
        let tol = match format {
            Format::Ply | Format::Splat => 0.0,
            Format::Spz => 0.5 / (1u32 << gs_export::spz::fractional_bits(&model).unwrap()) as f32 + extent * 1.2e-7,
            _ => 2.0 * extent / 2046.0,
        };
        for (k, &i) in write_order(format, &model).iter().enumerate() {
            for a in 0..3 {
                assert!((back.means[k][a] - model.means[i][a]).abs() <= tol, "{format}: Gaussian {i}");
            }
        }
        if format == Format::Ply {
            assert_eq!(back, model);
        }
    }

    // Independent readers.
    if python_has("plyfile") {
        let script = "import sys; from plyfile import PlyData\n\
            p = PlyData.read(sys.argv[1]); v = p['vertex']\n\
            print(v.count, len(v.properties), v['rot_3'].dtype, v['f_rest_44'].dtype)\n\
            c = PlyData.read(sys.argv[2])\n\
            print(' '.join(f'{e.name}:{e.count}:{len(e.properties)}:{e.properties[0].val_dtype}' for e in c.elements))\n\
            m = PlyData.read(sys.argv[3])\n\
            print(m['vertex'].count, m['face'].count, m['vertex']['red'].dtype, int(m['face']['vertex_indices'][0][2]))";
        let printed = python(script, &[&out("model.ply"), &out("model_compressed.ply"), &out("mesh_out.ply")]);
        let lines: Vec<&str> = printed.lines().collect();
        let n = model.len();
        assert_eq!(lines[0], format!("{n} 62 float32 float32"), "{printed}");
        let chunks = n.div_ceil(256);
        assert_eq!(lines[1], format!("chunk:{chunks}:18:f4 vertex:{n}:4:u4 sh:{n}:45:u1"), "{printed}");
        let t = mesh.triangles[0][2];
        assert_eq!(lines[2], format!("{} {} uint8 {t}", mesh.positions.len(), mesh.triangles.len()), "{printed}");
    }
    if python_has("pygltflib") && python_has("numpy") {
        let script = "import sys, numpy as np, pygltflib\n\
            g = pygltflib.GLTF2().load(sys.argv[1]); blob = g.binary_blob(); prim = g.meshes[0].primitives[0]\n\
            def acc(i, dt, w):\n    a = g.accessors[i]; v = g.bufferViews[a.bufferView]\n    return np.frombuffer(blob[v.byteOffset:v.byteOffset + v.byteLength], dtype=dt).reshape(-1, w)\n\
            pos = acc(prim.attributes.POSITION, '<f4', 3); idx = acc(prim.indices, '<u4', 3); col = acc(prim.attributes.COLOR_0, '<f4', 3)\n\
            print(pos.shape[0], idx.shape[0], repr(float(pos[0][0])), int(idx[-1][1]), bool((col >= 0).all() and (col <= 1).all()))";
        let printed = python(script, &[&out("mesh.glb")]);
        let last = mesh.triangles.len() - 1;
        let expect = format!("{} {} {:?} {} True", mesh.positions.len(), mesh.triangles.len(), mesh.positions[0][0] as f64, mesh.triangles[last][1]);
        assert_eq!(printed, expect);
    }
}

#[test]
fn bad_input_is_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let run = trained_run(dir.path(), false);
    let r = run.to_str().unwrap();
    let out_dir = dir.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    let o = |name: &str| out_dir.join(name).to_str().unwrap().to_string();
    let refused = |args: &[&str], words: &[&str]| {
        let (ok, _, err) = vagsl(args);
        assert!(!ok, "{args:?} succeeded");
        for w in words {
            assert!(err.contains(w), "{args:?}: '{w}' not in {err}");
        }
    };
    let missing = dir.path().join("no_run");
    refused(&["export", missing.to_str().unwrap(), "-o", &o("a.spz")], &["no_run", "no such run folder"]);
    refused(&["export", r, "-o", &o("mesh.obj")], &["no mesh.ply", &format!("vagsl mesh {r}")]);
    refused(&["export", r, "--format", "glb", "-o", &o("mesh.bin")], &["vagsl mesh"]);
    refused(&["export", r, "-o", &o("model.xyz")], &["model.xyz", "unknown extension '.xyz'", "--format"]);
    refused(&["export", r, "-o", &o("model.ply")], &["model.ply", "give --format"]);
    refused(&["export", r, "--format", "webp", "-o", &o("model.webp")], &["unknown format 'webp'"]);
    let file = out_dir.join("a_file");
    std::fs::write(&file, b"x").unwrap();
    let under_file = file.join("model.spz");
    refused(&["export", r, "-o", under_file.to_str().unwrap()], &["model.spz", "cannot write the spz file", &format!("{} is a file, not a folder", file.display())]);
    refused(&["export", r, "-o", "/nonexistent/folder/model.splat"], &["/nonexistent/folder", "does not exist"]);
    // The run's own files are never replaced by an export.
    let own = run.join("point_cloud.ply");
    let before = std::fs::read(&own).unwrap();
    refused(&["export", r, "--format", "compressed-ply", "-o", own.to_str().unwrap()], &["the run's own point_cloud.ply"]);
    assert_eq!(std::fs::read(&own).unwrap(), before);
    // A run folder whose model is missing.
    std::fs::remove_file(&own).unwrap();
    refused(&["export", r, "-o", &o("b.splat")], &["no point_cloud.ply"]);
    let left: Vec<_> = std::fs::read_dir(&out_dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(left, vec![std::ffi::OsString::from("a_file")], "something was written");
}
