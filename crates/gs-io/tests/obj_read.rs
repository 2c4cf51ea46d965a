//! OBJ reading: files on disk, polygons, groups, errors.

use gs_io::read_obj;

#[test]
fn reads_an_obj_file_with_quads_and_groups() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cube.obj");
    // A unit cube: 8 vertices, 6 quads, with normals and texture coordinates to ignore.
    let mut text = String::from("mtllib missing.mtl\n");
    for z in [0, 1] {
        for y in [0, 1] {
            for x in [0, 1] {
                text.push_str(&format!("v {x} {y} {z}\n"));
            }
        }
    }
    text.push_str("vn 0 0 1\nvt 0 0\ng bottom\nusemtl m\nf 1/1/1 3/1/1 4/1/1 2/1/1\ng rest\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\nl 1 2\n");
    std::fs::write(&path, text).unwrap();
    let m = read_obj(&path).unwrap();
    m.validate().unwrap();
    assert_eq!(m.triangles.len(), 12);
    assert!((m.area() - 6.0).abs() < 1e-9, "{}", m.area());
    let (lo, hi) = m.bounds().unwrap();
    assert_eq!((lo, hi), ([0.0; 3], [1.0; 3]));
}

#[test]
fn bad_obj_files_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.obj");
    std::fs::write(&path, "v 0 0 0\nv 1 0 0\nf 1 2 9\n").unwrap();
    let e = read_obj(&path).unwrap_err().to_string();
    assert!(e.contains("bad.obj"), "{e}");
    std::fs::write(&path, "v 0 nope 0\nf 1 1 1\n").unwrap();
    assert!(read_obj(&path).unwrap_err().to_string().contains("bad.obj"));
    std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n").unwrap();
    let e = read_obj(&path).unwrap_err().to_string();
    assert!(e.contains("bad.obj") && e.contains("not finite"), "{e}");
    assert!(read_obj(&dir.path().join("none.obj")).unwrap_err().to_string().contains("none.obj"));
}

/// Found by the `obj` fuzz target: tobj indexed normals (and texture coordinates) with
/// unchecked arithmetic, so an out-of-range relative normal index overflowed inside it, and a
/// huge one (`3 × index + 2` wrapping to 1) panicked in release builds. Normals and texture
/// coordinates are ignored, so these faces read as their positions.
#[test]
fn absurd_normal_and_texture_indices_are_ignored_not_a_panic() {
    let crash = b"# c\no a\nv 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nvn 0 0 1 0 v 0 1 0 0 n 0 0 1\nvt 0 0\nf 1/1/1 2/1/1 3/1/1\ng b\nv 5 5 50\nf 1/1/1 2/1/1 3/1/1\nvt 0 0\nf 1/1/1 2/1/1 3/1/-3\nl 1 2\np";
    let m = gs_io::obj::parse_obj(crash, std::path::Path::new("crash.obj")).unwrap();
    m.validate().unwrap();
    assert_eq!(m.triangles.len(), 3);
    let wrap = format!("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\nf 1/1/{i} 2/1/1 3/1/1\n", i = 6148914691236517206u64);
    let m = gs_io::obj::parse_obj(wrap.as_bytes(), std::path::Path::new("wrap.obj")).unwrap();
    assert_eq!(m.triangles, vec![[0, 1, 2]]);
}
