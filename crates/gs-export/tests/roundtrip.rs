//! Each format round-trips scene data within its stated quantisation: Gaussians built on the
//! built-in scene's sparse points (positions on its surfaces, colours from its textures; scales,
//! rotations, opacities and SH drawn around them, plus extreme values), and its objects'
//! ground-truth mesh (the folder gs-testdata writes, cached under target/).
//! The maxima measured are printed (`--nocapture`).

use gs_core::gaussians::sigmoid;
use gs_core::sh::{SH_C0, SH_COEFFS};
use gs_core::{Gaussians, Rng, TriangleMesh};
use gs_export::{ExportError, Format, read_gaussians, read_mesh, write_gaussians, write_mesh, write_order};
use std::path::PathBuf;

/// A file of the built-in scene folder with 12,000 sparse points (as many as a small capture).
fn builtin(rel: &str) -> PathBuf {
    let opts = gs_synth::BuiltinOptions { points: 12_000, ..gs_testdata::builtin::small() };
    gs_testdata::builtin::scene_dir(std::path::Path::new(env!("CARGO_TARGET_TMPDIR")), &opts).join(rel)
}

/// The built-in scene's sparse points as degree-3 Gaussians, plus four with extreme parameters.
fn scene_gaussians() -> Gaussians {
    let model = gs_io::read_model(&builtin("sparse/0")).unwrap();
    let mut rng = Rng::new(7);
    let mut g = Gaussians::default();
    for p in model.points3d.values() {
        let mut sh = [[0f32; 3]; SH_COEFFS];
        sh[0] = p.rgb.map(|c| gs_core::gaussians::rgb_to_sh_dc(c as f32 / 255.0));
        for c in sh.iter_mut().skip(1) {
            *c = [0.2 * rng.normal(), 0.2 * rng.normal(), 0.2 * rng.normal()];
        }
        let ls = [0, 1, 2].map(|_| -4.5 + rng.normal());
        let q = [rng.normal(), rng.normal(), rng.normal(), rng.normal()];
        g.push(p.xyz.map(|v| v as f32), ls, q, 2.0 * rng.normal(), sh);
    }
    let mut wild = [[0f32; 3]; SH_COEFFS];
    wild[0] = [5.0, -5.0, 0.0];
    wild[1] = [1.5, -1.5, 0.99];
    wild[9] = [5.0, -5.0, 3.9];
    g.push([0.0, 0.0, 0.0], [-12.0, 7.0, 0.0], [0.0, 0.0, 0.0, 1.0], 20.0, wild);
    g.push([1.0, 1.0, 1.0], [-25.0, 25.0, -3.0], [-1.0, 0.0, 0.0, 0.0], -20.0, wild);
    g.push([0.1, 0.2, 0.3], [-3.0; 3], [0.5, 0.5, -0.5, 0.5], 0.0, [[0.0; 3]; SH_COEFFS]);
    g.push([0.1, 0.2, 0.3], [-3.0; 3], [0.0; 4], 0.0, [[0.0; 3]; SH_COEFFS]);
    g.sh_degree = 3;
    g.validate().unwrap();
    g
}

/// The unit quaternion (identity for a zero one), sign-aligned with `to`.
fn unit_aligned(q: [f32; 4], to: [f32; 4]) -> [f32; 4] {
    let u = gs_core::gaussians::unit_quaternion(q);
    let dot: f32 = u.iter().zip(to).map(|(a, b)| a * b).sum();
    if dot < 0.0 { u.map(|v| -v) } else { u }
}

/// Largest deviations seen, by quantity.
#[derive(Default, Debug)]
struct Max(std::collections::BTreeMap<&'static str, f32>);

impl Max {
    /// Records `err` for `what` and asserts it is within `bound`.
    fn check(&mut self, what: &'static str, i: usize, err: f32, bound: f32) {
        assert!(err <= bound, "{what} of Gaussian {i}: error {err} > bound {bound}");
        let m = self.0.entry(what).or_insert(0.0);
        *m = m.max(err);
    }
}

/// Writes `g` in `format`, reads it back, and returns the read Gaussians in `g`'s order.
fn round_trip(format: Format, g: &Gaussians) -> Gaussians {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(format!("model.{}", format.name()));
    write_gaussians(format, &path, g, false).unwrap();
    let read = read_gaussians(format, &path).unwrap();
    assert_eq!(read.len(), g.len());
    let order = write_order(format, g);
    let mut back = Gaussians::with_len(g.len()).unwrap();
    for (k, &i) in order.iter().enumerate() {
        back.means[i] = read.means[k];
        back.log_scales[i] = read.log_scales[k];
        back.rotations[i] = read.rotations[k];
        back.opacity_logits[i] = read.opacity_logits[k];
        back.sh[i] = read.sh[k];
    }
    back.sh_degree = read.sh_degree;
    back
}

fn check_opacity(max: &mut Max, g: &Gaussians, b: &Gaussians, i: usize) {
    max.check("opacity", i, (sigmoid(b.opacity_logits[i]) - sigmoid(g.opacity_logits[i])).abs(), 0.5 / 255.0 + 1e-6);
}

/// The decoded rotation of Gaussian `i` against the original, both as unit quaternions with
/// the sign aligned (q and −q are one rotation), per component within `tol`.
fn check_rotation(max: &mut Max, g: &Gaussians, b: &Gaussians, i: usize, tol: f32) {
    let u = gs_core::gaussians::unit_quaternion(g.rotations[i]);
    let v = unit_aligned(b.rotations[i], u);
    for k in 0..4 {
        max.check("quaternion component", i, (v[k] - u[k]).abs(), tol);
    }
}

#[test]
fn ply_is_lossless() {
    let g = scene_gaussians();
    assert_eq!(round_trip(Format::Ply, &g), g);
}

#[test]
fn splat_round_trip() {
    let g = scene_gaussians();
    let b = round_trip(Format::Splat, &g);
    assert_eq!(b.sh_degree, 0);
    let mut max = Max::default();
    for i in 0..g.len() {
        assert_eq!(b.means[i], g.means[i]);
        for k in 0..3 {
            let ls = g.log_scales[i][k];
            max.check("log-scale", i, (b.log_scales[i][k] - ls).abs(), 2e-6 * ls.abs().max(1.0));
            let c = (0.5 + SH_C0 * g.sh[i][0][k]).clamp(0.0, 1.0);
            max.check("colour", i, (0.5 + SH_C0 * b.sh[i][0][k] - c).abs(), 0.5 / 255.0 + 1e-6);
        }
        check_opacity(&mut max, &g, &b, i);
        let u = gs_core::gaussians::unit_quaternion(g.rotations[i]);
        for (r, v) in b.rotations[i].iter().zip(u) {
            max.check("quaternion component", i, (r - v).abs(), 1.0 / 128.0 + 1e-6);
        }
        assert!(b.sh[i][1..].iter().flatten().all(|&v| v == 0.0));
    }
    eprintln!("splat: {max:?}");
}

#[test]
fn spz_round_trip() {
    let g = scene_gaussians();
    let fb = gs_export::spz::fractional_bits(&g).unwrap();
    let b = round_trip(Format::Spz, &g);
    assert_eq!(b.sh_degree, 3);
    let mut max = Max::default();
    for i in 0..g.len() {
        for k in 0..3 {
            let p = g.means[i][k];
            max.check("position", i, (b.means[i][k] - p).abs(), 0.5 / (1u32 << fb) as f32 + p.abs() * 1.2e-7);
            let ls = g.log_scales[i][k].clamp(-10.0, 15.0 / 16.0 + 5.0);
            max.check("log-scale", i, (b.log_scales[i][k] - ls).abs(), 1.0 / 32.0 + 1e-5);
            let dc = g.sh[i][0][k].clamp(-127.5 / 38.25, 127.5 / 38.25);
            max.check("f_dc", i, (b.sh[i][0][k] - dc).abs(), 0.5 / 38.25 + 1e-5);
            for c in 1..SH_COEFFS {
                let (what, bound) = if c <= 3 { ("sh degree 1", 4.5 / 128.0) } else { ("sh degree 2-3", 8.5 / 128.0) };
                max.check(what, i, (b.sh[i][c][k] - g.sh[i][c][k].clamp(-1.0, 1.0)).abs(), bound + 1e-6);
            }
        }
        check_opacity(&mut max, &g, &b, i);
        check_rotation(&mut max, &g, &b, i, 2e-3);
    }
    eprintln!("spz (fractional bits {fb}): {max:?}");
}

/// The antialiased flag is bit 0x1 of the header's flags byte (byte 14 of the decompressed
/// stream, as Niantic's `PackedGaussiansHeader` lays it out), read back by the decoder; the
/// Gaussians are the same bytes either way.
#[test]
fn spz_records_the_antialiased_flag() {
    let g = scene_gaussians();
    let dir = tempfile::tempdir().unwrap();
    let mut streams = Vec::new();
    for antialiased in [false, true] {
        let path = dir.path().join(format!("aa-{antialiased}.spz"));
        write_gaussians(Format::Spz, &path, &g, antialiased).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let mut raw = Vec::new();
        std::io::Read::read_to_end(&mut flate2::read::GzDecoder::new(&bytes[..]), &mut raw).unwrap();
        assert_eq!(raw[14], u8::from(antialiased), "flags byte");
        assert_eq!(gs_export::spz::decode_spz(&bytes, &path).unwrap().1, antialiased);
        raw[14] = 0;
        streams.push(raw);
    }
    assert_eq!(streams[0], streams[1], "only the flag differs");
    assert!(Format::Spz.records_antialiasing());
    assert!(Format::ALL.iter().filter(|f| f.records_antialiasing()).count() == 1);
}

#[test]
fn compressed_ply_round_trip() {
    let g = scene_gaussians();
    let b = round_trip(Format::CompressedPly, &g);
    assert_eq!(b.sh_degree, 3);
    let mut max = Max::default();
    for members in write_order(Format::CompressedPly, &g).chunks(256) {
        let range = |f: &dyn Fn(usize) -> f32| {
            members.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &i| (lo.min(f(i)), hi.max(f(i))))
        };
        for k in 0..3 {
            let steps = if k == 1 { 2.0 * 1023.0 } else { 2.0 * 2047.0 };
            let (lo, hi) = range(&|i| g.means[i][k]);
            let (slo, shi) = range(&|i| g.log_scales[i][k].clamp(-20.0, 20.0));
            let (clo, chi) = range(&|i| 0.5 + SH_C0 * g.sh[i][0][k]);
            for &i in members {
                let tol = 1e-5 + 2e-7 * lo.abs().max(hi.abs());
                max.check("position / chunk range", i, (b.means[i][k] - g.means[i][k]).abs() / (hi - lo).max(1e-12), 1.0 / steps + tol / (hi - lo).max(1e-12));
                let ls = g.log_scales[i][k].clamp(-20.0, 20.0);
                max.check("log-scale / chunk range", i, (b.log_scales[i][k] - ls).abs() / (shi - slo).max(1e-12), 1.0 / steps + 1e-5 / (shi - slo).max(1e-12));
                let c = (0.5 + SH_C0 * b.sh[i][0][k] - (0.5 + SH_C0 * g.sh[i][0][k])).abs();
                max.check("colour / chunk range", i, c / (chi - clo).max(1e-12), 1.0 / 510.0 + 1e-5 / (chi - clo).max(1e-12));
                for c in 1..SH_COEFFS {
                    max.check("sh", i, (b.sh[i][c][k] - g.sh[i][c][k].clamp(-4.0, 4.0)).abs(), 1.0 / 32.0 + 1e-6);
                }
            }
        }
        for &i in members {
            check_opacity(&mut max, &g, &b, i);
            check_rotation(&mut max, &g, &b, i, 2e-3);
        }
    }
    eprintln!("compressed-ply: {max:?}");
}

#[test]
fn lower_sh_degrees_round_trip() {
    for degree in [0, 1, 2] {
        let mut g = scene_gaussians();
        g.sh_degree = degree;
        let keep = (degree as usize + 1).pow(2);
        g.sh.iter_mut().for_each(|s| s[keep..].iter_mut().for_each(|c| *c = [0.0; 3]));
        for format in [Format::Spz, Format::CompressedPly] {
            let b = round_trip(format, &g);
            assert_eq!(b.sh_degree, degree, "{format}");
            assert!(b.sh.iter().all(|s| s[keep..].iter().flatten().all(|&v| v == 0.0)), "{format}");
        }
    }
}

/// The built-in scene's ground-truth object mesh, with colours from its positions when `colors`.
fn object_mesh(colors: bool) -> TriangleMesh {
    let mut m = gs_io::read_mesh_ply(&builtin("gt_mesh.ply")).unwrap();
    let (lo, hi) = m.bounds().unwrap();
    m.colors = colors.then(|| {
        m.positions.iter().map(|p| [0, 1, 2].map(|k| ((p[k] - lo[k]) / (hi[k] - lo[k]) * 255.0).round() as u8)).collect()
    });
    m
}

/// Each triangle's corners: position bits and colour.
fn corners(m: &TriangleMesh) -> Vec<([u32; 3], Option<[u8; 3]>)> {
    m.triangles.iter().flatten().map(|&v| (m.positions[v as usize].map(f32::to_bits), m.colors.as_ref().map(|c| c[v as usize]))).collect()
}

#[test]
fn meshes_round_trip_exactly() {
    let dir = tempfile::tempdir().unwrap();
    for colors in [true, false] {
        let m = object_mesh(colors);
        for format in [Format::MeshPly, Format::Obj, Format::Glb] {
            let path = dir.path().join(format!("mesh.{}", format.name()));
            write_mesh(format, &path, &m).unwrap();
            let back = read_mesh(format, &path).unwrap();
            // tobj drops vertices no face uses and numbers the rest by first use, so compare the
            // triangles corner by corner (PLY and GLB keep the vertex list as it is).
            assert_eq!(corners(&back), corners(&m), "{format} with colours {colors}");
            if format != Format::Obj {
                assert_eq!(back, m, "{format} with colours {colors}");
            }
            assert_eq!(back.colors.is_some(), colors, "{format}: colours lost or invented");
        }
    }
}

#[test]
fn formats_from_names_and_extensions() {
    for f in Format::ALL {
        assert_eq!(Format::from_name(f.name()), Some(f));
    }
    let from = |p: &str| Format::from_path(std::path::Path::new(p));
    assert_eq!(from("a/b.SPZ").unwrap(), Format::Spz);
    assert_eq!(from("b.splat").unwrap(), Format::Splat);
    assert_eq!(from("b.glb").unwrap(), Format::Glb);
    assert_eq!(from("b.obj").unwrap(), Format::Obj);
    for (p, words) in [("b.ply", "give --format"), ("b.xyz", "unknown extension '.xyz'"), ("b", "no extension")] {
        let e = from(p).unwrap_err().to_string();
        assert!(e.starts_with(p) && e.contains(words), "{e}");
    }
}

#[test]
fn failed_writes_leave_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let g = scene_gaussians();
    let missing = dir.path().join("no/such/folder/model.spz");
    let e = write_gaussians(Format::Spz, &missing, &g, false).unwrap_err().to_string();
    assert!(e.contains("model.spz"), "{e}");
    // A model spz cannot hold: nothing is written, an existing file is kept.
    let path = dir.path().join("far.spz");
    std::fs::write(&path, b"old").unwrap();
    let mut far = g.clone();
    far.means[0] = [1e8, 0.0, 0.0];
    let e = write_gaussians(Format::Spz, &path, &far, false).unwrap_err();
    assert!(matches!(e, ExportError::Unencodable { .. }) && e.to_string().contains("24-bit"), "{e}");
    let mut nan = g.clone();
    nan.means[3][0] = f32::NAN;
    assert!(write_gaussians(Format::Splat, &path, &nan, false).is_err());
    let empty = TriangleMesh::default();
    let e = write_mesh(Format::Glb, &path.with_extension("glb"), &empty).unwrap_err().to_string();
    assert!(e.contains("no triangles"), "{e}");
    assert!(write_mesh(Format::Spz, &path, &object_mesh(false)).is_err());
    assert_eq!(std::fs::read(&path).unwrap(), b"old");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "only far.spz");
}

/// Truncated and corrupted files give errors naming the file, never a panic.
#[test]
fn damaged_files_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = scene_gaussians();
    g.retain(&(0..g.len()).map(|i| i < 600).collect::<Vec<_>>()).unwrap();
    let mut rng = Rng::new(3);
    for format in [Format::Splat, Format::Spz, Format::CompressedPly, Format::Glb] {
        let good = dir.path().join(format!("good.{}", format.name()));
        if format.is_mesh() {
            write_mesh(format, &good, &object_mesh(true)).unwrap();
        } else {
            write_gaussians(format, &good, &g, false).unwrap();
        }
        let bytes = std::fs::read(&good).unwrap();
        let bad = dir.path().join(format!("bad.{}", format.name()));
        for cut in [0, 1, 15, 100, bytes.len() / 2, bytes.len() - 1] {
            std::fs::write(&bad, &bytes[..cut]).unwrap();
            let r = if format.is_mesh() { read_mesh(format, &bad).map(|_| ()) } else { read_gaussians(format, &bad).map(|_| ()) };
            match r {
                Ok(()) => assert!(format == Format::Splat && cut % 32 == 0, "{format} cut at {cut} was accepted"),
                Err(e) => assert!(e.to_string().contains("bad."), "{format} cut at {cut}: {e}"),
            }
        }
        for _ in 0..50 {
            let mut b = bytes.clone();
            for _ in 0..4 {
                let k = (rng.uniform() * b.len() as f32) as usize % b.len();
                b[k] ^= 1 << ((rng.uniform() * 8.0) as u32 % 8);
            }
            std::fs::write(&bad, &b).unwrap();
            let _ = if format.is_mesh() { read_mesh(format, &bad).map(|_| ()) } else { read_gaussians(format, &bad).map(|_| ()) };
        }
    }
    let v4 = dir.path().join("v4.spz");
    std::fs::write(&v4, b"NGSP\x04\0\0\0").unwrap();
    let e = read_gaussians(Format::Spz, &v4).unwrap_err().to_string();
    assert!(e.contains("version 4"), "{e}");
}
