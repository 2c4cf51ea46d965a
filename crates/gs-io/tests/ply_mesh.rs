//! Mesh PLY: exact round trips (with and without colours) and the synth-bunny ground truth.

use gs_core::{Rng, TriangleMesh};
use gs_io::ply::read_header;
use gs_io::{read_mesh_ply, write_mesh_ply};
use std::path::PathBuf;

fn shared(rel: &str) -> PathBuf {
    gs_testdata::root().join("data/synth-bunny").join(rel)
}

fn random_mesh(nv: usize, nt: usize, colours: bool, seed: u64) -> TriangleMesh {
    let mut rng = Rng::new(seed);
    let positions = (0..nv).map(|_| [rng.normal() * 1e3, rng.normal(), -rng.uniform() * 1e-30]).collect();
    let triangles = (0..nt)
        .map(|_| [rng.below(nv as u64) as u32, rng.below(nv as u64) as u32, rng.below(nv as u64) as u32])
        .collect();
    let colors = colours.then(|| (0..nv).map(|_| [rng.below(256) as u8, rng.below(256) as u8, rng.below(256) as u8]).collect());
    TriangleMesh { positions, triangles, colors }
}

#[test]
fn round_trip_is_exact_with_and_without_colours() {
    let dir = tempfile::tempdir().unwrap();
    for colours in [false, true] {
        let m = random_mesh(500, 900, colours, 3 + colours as u64);
        let path = dir.path().join(format!("m{colours}.ply"));
        write_mesh_ply(&path, &m).unwrap();
        let back = read_mesh_ply(&path).unwrap();
        assert_eq!(back.colors.is_some(), colours);
        assert_eq!(back.triangles, m.triangles);
        let a: Vec<u32> = m.positions.iter().flatten().map(|v| v.to_bits()).collect();
        let b: Vec<u32> = back.positions.iter().flatten().map(|v| v.to_bits()).collect();
        assert_eq!(a, b);
        assert_eq!(back, m);
        let h = read_header(&path).unwrap();
        let names: Vec<&str> = h.elements[0].properties.iter().map(|p| p.name.as_str()).collect();
        let expect: &[&str] = if colours { &["x", "y", "z", "red", "green", "blue"] } else { &["x", "y", "z"] };
        assert_eq!(names, expect);
        assert_eq!(h.elements[1].properties[0].name, "vertex_indices");
    }
    // An empty mesh too.
    let path = dir.path().join("empty.ply");
    write_mesh_ply(&path, &TriangleMesh::default()).unwrap();
    assert_eq!(read_mesh_ply(&path).unwrap(), TriangleMesh::default());
}

#[test]
fn invalid_mesh_is_not_written() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.ply");
    let mut m = random_mesh(4, 2, false, 1);
    m.triangles.push([0, 1, 4]);
    let e = write_mesh_ply(&path, &m).unwrap_err().to_string();
    assert!(e.contains("bad.ply") && e.contains("triangle 2"), "{e}");
    assert!(!path.exists());
}

#[test]
fn reads_the_synth_bunny_ground_truth_meshes() {
    if !gs_testdata::needs!("data/synth-bunny") {
        return;
    }
    let bunny = read_mesh_ply(&shared("gt_mesh.ply")).unwrap();
    assert_eq!(bunny.positions.len(), 35_947);
    assert_eq!(bunny.triangles.len(), 69_451);
    assert!(bunny.colors.is_none());
    bunny.validate().unwrap();
    // README: bunny bounding box x ∈ [−0.504422, 0.504422], z ∈ [0, 1].
    let (lo, hi) = bunny.bounds().unwrap();
    assert!((lo[0] + 0.504422).abs() < 1e-5 && (hi[0] - 0.504422).abs() < 1e-5, "{lo:?} {hi:?}");
    assert!(lo[2].abs() < 1e-5 && (hi[2] - 1.0).abs() < 1e-5, "{lo:?} {hi:?}");

    let scene = read_mesh_ply(&shared("gt_scene_mesh.ply")).unwrap();
    assert_eq!(scene.positions.len(), 35_967);
    assert_eq!(scene.triangles.len(), 69_461);
    scene.validate().unwrap();
    // The bunny comes first with the same indices.
    assert_eq!(&scene.positions[..35_947], &bunny.positions[..]);
    assert_eq!(&scene.triangles[..69_451], &bunny.triangles[..]);
}

#[test]
fn ascii_mesh_reads_like_the_binary_one() {
    let m = random_mesh(30, 40, true, 9);
    let mut text = format!(
        "ply\nformat ascii 1.0\ncomment from some tool\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face {}\nproperty list uchar int vertex_indices\nelement edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n",
        m.positions.len(),
        m.triangles.len()
    );
    let cs = m.colors.as_ref().unwrap();
    for (p, c) in m.positions.iter().zip(cs) {
        // `{:?}` prints the shortest string that parses back to the same f32.
        text.push_str(&format!("{:?} {:?} {:?} {} {} {}\n", p[0], p[1], p[2], c[0], c[1], c[2]));
    }
    for t in &m.triangles {
        text.push_str(&format!("3 {} {} {}\n", t[0], t[1], t[2]));
    }
    text.push_str("0 1\n");
    let back = gs_io::parse_mesh_ply(text.as_bytes(), std::path::Path::new("a.ply")).unwrap();
    assert_eq!(back, m);
}
