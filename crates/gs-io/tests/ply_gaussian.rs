//! Gaussian PLY: bit-exact round trips, the Inria property list, the golden fixture that the
//! Python `plyfile` check reads, and reading files of lower SH degree.

use gs_core::sh::{SH_COEFFS, coeffs_for_degree};
use gs_core::{Gaussians, Rng};
use gs_io::ply::gaussian::{gaussian_property_names, write_gaussian_ply_to};
use gs_io::ply::{PropertyKind, ScalarType, read_header};
use gs_io::{parse_gaussian_ply, read_gaussian_ply, write_gaussian_ply};
use std::path::{Path, PathBuf};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/ply").join(name)
}

/// Random Gaussians of `degree` with extreme values mixed in (log-scales −20/+10, logits ±30,
/// tiny/huge SH, negative zero, subnormals).
fn random_gaussians(n: usize, degree: u32, seed: u64) -> Gaussians {
    let mut rng = Rng::new(seed);
    let extremes = [-20.0f32, 10.0, 30.0, -30.0, -0.0, 1e-38, f32::MIN_POSITIVE / 8.0, 3.4e38, -1e30];
    let pick = |rng: &mut Rng| {
        if rng.below(4) == 0 { extremes[rng.below(extremes.len() as u64) as usize] } else { rng.normal() * 5.0 }
    };
    let mut g = Gaussians::default();
    for _ in 0..n {
        let mut sh = [[0f32; 3]; SH_COEFFS];
        for c in sh.iter_mut().take(coeffs_for_degree(degree)) {
            *c = [pick(&mut rng), pick(&mut rng), pick(&mut rng)];
        }
        let ls = [
            [-20.0, 10.0, pick(&mut rng)][rng.below(3) as usize],
            pick(&mut rng),
            pick(&mut rng),
        ];
        let logit = [30.0, -30.0, pick(&mut rng)][rng.below(3) as usize];
        g.push(
            [pick(&mut rng), pick(&mut rng), pick(&mut rng)],
            ls,
            [pick(&mut rng), pick(&mut rng), pick(&mut rng), pick(&mut rng)],
            logit,
            sh,
        );
    }
    g.sh_degree = degree;
    g
}

fn bits(g: &Gaussians) -> Vec<u32> {
    let mut v: Vec<u32> = Vec::new();
    for i in 0..g.len() {
        v.extend(g.means[i].iter().map(|x| x.to_bits()));
        v.extend(g.log_scales[i].iter().map(|x| x.to_bits()));
        v.extend(g.rotations[i].iter().map(|x| x.to_bits()));
        v.push(g.opacity_logits[i].to_bits());
        v.extend(g.sh[i].iter().flatten().map(|x| x.to_bits()));
    }
    v
}

#[test]
fn round_trip_is_bit_exact_for_every_degree() {
    let dir = tempfile::tempdir().unwrap();
    for degree in 0..=3 {
        let g = random_gaussians(777, degree, 11 + degree as u64);
        g.validate().unwrap();
        let path = dir.path().join(format!("g{degree}.ply"));
        write_gaussian_ply(&path, &g).unwrap();
        let back = read_gaussian_ply(&path).unwrap();
        assert_eq!(back.sh_degree, degree);
        assert_eq!(back.len(), g.len());
        assert_eq!(bits(&back), bits(&g), "degree {degree}");
    }
    // Degree-0 model with non-zero higher coefficients: all 45 f_rest are stored, so they survive.
    let mut g = random_gaussians(10, 3, 5);
    g.sh_degree = 0;
    let path = dir.path().join("hidden.ply");
    write_gaussian_ply(&path, &g).unwrap();
    let back = read_gaussian_ply(&path).unwrap();
    assert_eq!(back.sh_degree, 0);
    assert_eq!(bits(&back), bits(&g));
    // Only the final file remains (atomic write).
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 5);
}

#[test]
fn empty_model_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("empty.ply");
    write_gaussian_ply(&path, &Gaussians::default()).unwrap();
    assert!(read_gaussian_ply(&path).unwrap().is_empty());
}

#[test]
fn written_header_has_the_exact_inria_property_list() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("h.ply");
    write_gaussian_ply(&path, &random_gaussians(3, 3, 1)).unwrap();
    let header = read_header(&path).unwrap();
    assert_eq!(header.encoding, gs_io::ply::PlyEncoding::BinaryLittleEndian);
    assert_eq!(header.elements.len(), 1);
    let vertex = &header.elements[0];
    assert_eq!((vertex.name.as_str(), vertex.count), ("vertex", 3));
    let names: Vec<&str> = vertex.properties.iter().map(|p| p.name.as_str()).collect();
    // Written out literally (not generated) so that a change of the layout cannot go unnoticed.
    let mut expected: Vec<String> = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"].map(String::from).to_vec();
    for i in 0..45 {
        expected.push(format!("f_rest_{i}"));
    }
    expected.extend(["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"].map(String::from));
    assert_eq!(names, expected);
    assert_eq!(names.len(), 62);
    assert_eq!(gaussian_property_names(), expected);
    assert!(vertex.properties.iter().all(|p| p.kind == PropertyKind::Scalar(ScalarType::F32)));
    // 62 floats per vertex after the header.
    let len = std::fs::metadata(&path).unwrap().len() as usize;
    assert_eq!(len - header.data_offset, 3 * 62 * 4);
}

/// The small model stored as `tests/fixtures/ply/gaussians_small.ply` (read by
/// `scripts/check_ply_plyfile.py`): a formula, so the fixture does not depend on the RNG.
fn fixture_model() -> Gaussians {
    let mut g = Gaussians::default();
    for i in 0..4 {
        let f = i as f32;
        let mut sh = [[0f32; 3]; SH_COEFFS];
        for (k, c) in sh.iter_mut().enumerate() {
            for (ch, v) in c.iter_mut().enumerate() {
                *v = f * 100.0 + (ch * 16 + k) as f32 * 0.5;
            }
        }
        g.push([f, -f, 0.5 * f], [-4.0 - f, -3.0, 1.0], [1.0, 0.1 * f, 0.0, -0.2], 2.0 - f, sh);
    }
    g.sh_degree = 3;
    g
}

#[test]
fn golden_fixture_matches_the_writer() {
    let path = fixture("gaussians_small.ply");
    let mut bytes = Vec::new();
    write_gaussian_ply_to(&mut bytes, &fixture_model()).unwrap();
    if std::env::var_os("VAGSL_BLESS").is_some() {
        std::fs::write(&path, &bytes).unwrap();
    }
    let stored = std::fs::read(&path).expect("fixture missing: run with VAGSL_BLESS=1 to create it");
    assert_eq!(stored, bytes, "writer output changed; re-run scripts/check_ply_plyfile.py before re-blessing");
    assert_eq!(parse_gaussian_ply(&stored, &path).unwrap(), fixture_model());
    // The plyfile check's recorded output lists the same names in the same order.
    let out = std::fs::read_to_string(fixture("plyfile_check_output.txt")).unwrap();
    let listed: Vec<String> = out
        .lines()
        .find_map(|l| l.strip_prefix("properties: "))
        .expect("a 'properties:' line")
        .split_whitespace()
        .map(String::from)
        .collect();
    assert_eq!(listed, gaussian_property_names());
    assert!(out.contains("vertex count: 4"), "{out}");
    // f_rest_15 of Gaussian 1 is G coefficient 1: 100 + (16 + 1) * 0.5.
    assert!(out.contains("gaussian 1 f_rest_15: 108.5"), "{out}");
}

#[test]
fn lower_degree_inria_files_read_with_their_degree() {
    // Write binary files with 0, 9 and 24 f_rest fields by hand (Inria with max_sh_degree < 3).
    for (degree, rest) in [(0u32, 0usize), (1, 9), (2, 24)] {
        let g = random_gaussians(20, degree, 40 + degree as u64);
        let per = rest / 3;
        let mut text = format!("ply\nformat binary_little_endian 1.0\nelement vertex {}\n", g.len());
        let mut names: Vec<String> = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"].map(String::from).to_vec();
        names.extend((0..rest).map(|i| format!("f_rest_{i}")));
        names.extend(["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"].map(String::from));
        for n in &names {
            text.push_str(&format!("property float {n}\n"));
        }
        text.push_str("end_header\n");
        let mut bytes = text.into_bytes();
        for i in 0..g.len() {
            let mut vals: Vec<f32> = g.means[i].to_vec();
            vals.extend([0.0; 3]);
            vals.extend(g.sh[i][0]);
            for c in 0..3 {
                for k in 1..=per {
                    vals.push(g.sh[i][k][c]);
                }
            }
            vals.push(g.opacity_logits[i]);
            vals.extend(g.log_scales[i]);
            vals.extend(g.rotations[i]);
            for v in vals {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
        let back = parse_gaussian_ply(&bytes, Path::new("low.ply")).unwrap();
        assert_eq!(back.sh_degree, degree);
        assert_eq!(bits(&back), bits(&g), "degree {degree}");
    }
}

#[test]
fn big_endian_double_file_reads_the_same_values() {
    let g = random_gaussians(6, 3, 3);
    let names = gaussian_property_names();
    let mut text = format!("ply\nformat binary_big_endian 1.0\nelement vertex {}\n", g.len());
    for n in &names {
        text.push_str(&format!("property double {n}\n"));
    }
    text.push_str("property uchar extra\nend_header\n");
    let mut le = Vec::new();
    write_gaussian_ply_to(&mut le, &g).unwrap();
    let h = gs_io::ply::parse_header(&le, Path::new("le")).unwrap();
    let mut bytes = text.into_bytes();
    for rec in le[h.data_offset..].chunks_exact(62 * 4) {
        for v in rec.chunks_exact(4) {
            let f = f32::from_le_bytes(v.try_into().unwrap());
            bytes.extend_from_slice(&(f as f64).to_be_bytes());
        }
        bytes.push(7);
    }
    let back = parse_gaussian_ply(&bytes, Path::new("be.ply")).unwrap();
    assert_eq!(bits(&back), bits(&g));
}
