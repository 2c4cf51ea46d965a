//! Every reader under the one size cap (`gs_io::capped`): a header declaring more than the file
//! holds, a file larger than its kind's cap (sparse, so nothing is written), an endless device
//! and a cut file are each refused with a message naming the file, what it declares or holds,
//! and the cap; never an allocation of the declared size, a panic or an out-of-memory kill.

use gs_core::{Gaussians, TriangleMesh};
use gs_io::capped::{COLMAP, Cap, IMAGE, NPY, OBJ, PLY};
use std::path::{Path, PathBuf};

mod common;
use common::npy;

fn assert_has(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "error {msg:?} lacks {p:?}");
    }
}

/// A file starting with `head`, then holes up to one byte over `cap` (no disk space used).
fn sparse_over(dir: &Path, name: &str, head: &[u8], cap: Cap) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, head).unwrap();
    std::fs::OpenOptions::new().write(true).open(&p).unwrap().set_len(cap.bytes + 1).unwrap();
    p
}

/// The message of a file over its cap: names the file, its size and the cap.
fn over_cap(e: gs_io::IoError, p: &Path, cap: Cap) -> String {
    let e = e.to_string();
    let size = gs_io::capped::bytes(cap.bytes + 1);
    let cap_words = format!("more than the cap of {} for {}", gs_io::capped::bytes(cap.bytes), cap.what);
    assert_has(&e, &[&p.display().to_string(), &format!("the file holds {size}"), &cap_words]);
    e
}

fn gaussian_ply(n: usize) -> Vec<u8> {
    let mut g = Gaussians::with_len(n).unwrap();
    g.sh_degree = 3;
    let mut buf = Vec::new();
    gs_io::ply::gaussian::write_gaussian_ply_to(&mut buf, &g).unwrap();
    buf
}

#[test]
fn ply_headers_files_and_devices() {
    let dir = tempfile::tempdir().unwrap();
    // A header declaring 10^12 vertices in a few hundred bytes: refused before allocating.
    let text = String::from_utf8_lossy(&gaussian_ply(1)).replacen("element vertex 1\n", "element vertex 1000000000000\n", 1);
    let p = dir.path().join("absurd.ply");
    std::fs::write(&p, text.as_bytes()).unwrap();
    let e = gs_io::read_gaussian_ply(&p).unwrap_err().to_string();
    assert_has(&e, &["absurd.ply: element 'vertex' declares 1000000000000 records of at least 248 bytes each (225.6 TiB)", "the cap for a PLY file is 11.5 GiB"]);
    // A valid header at the front of a sparse file over the cap: refused from its size.
    let p = sparse_over(dir.path(), "huge.ply", &gaussian_ply(1), PLY);
    over_cap(gs_io::read_gaussian_ply(&p).unwrap_err(), &p, PLY);
    over_cap(gs_io::read_mesh_ply(&p).unwrap_err(), &p, PLY);
    // An endless device: read up to the 1 GiB pipe cap, then refused, in seconds.
    let t = std::time::Instant::now();
    let e = gs_io::read_mesh_ply(Path::new("/dev/zero")).unwrap_err().to_string();
    assert_eq!(e, "/dev/zero: it gives more than the cap of 1 GiB for a PLY file read from a pipe or device");
    assert!(t.elapsed().as_secs() < 30, "{:?}", t.elapsed());
    // A cut mesh names the file.
    let mesh = TriangleMesh { positions: vec![[0.0; 3]; 3], triangles: vec![[0, 1, 2]], colors: None };
    let mut bytes = Vec::new();
    gs_io::ply::mesh::write_mesh_ply_to(&mut bytes, &mesh).unwrap();
    let e = gs_io::parse_mesh_ply(&bytes[..bytes.len() - 4], Path::new("cut.ply")).unwrap_err().to_string();
    assert!(e.starts_with("cut.ply: "), "{e}");
}

/// A PNG of `w` × `h` whose IHDR was rewritten to declare `w2` × `h2` (CRC fixed).
fn png_declaring(w2: u32, h2: u32) -> Vec<u8> {
    let img = image::RgbImage::new(4, 4);
    let mut v = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut v), image::ImageFormat::Png).unwrap();
    // Signature (8), length (4), "IHDR" (4), then width and height.
    v[16..20].copy_from_slice(&w2.to_be_bytes());
    v[20..24].copy_from_slice(&h2.to_be_bytes());
    let crc = crc32(&v[12..29]);
    v[29..33].copy_from_slice(&crc.to_be_bytes());
    v
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
        }
    }
    !c
}

#[test]
fn images_by_header_size_and_device() {
    let dir = tempfile::tempdir().unwrap();
    // 10^9 × 10^9 pixels declared in 70 bytes: refused from the header.
    let p = dir.path().join("giant.png");
    std::fs::write(&p, png_declaring(1_000_000_000, 1_000_000_000)).unwrap();
    // The image crate's Limits refuse it (a side over 65536 pixels) in the header.
    let caps = "(caps: 65536 pixels a side, 67108864 pixels, 512 MiB decoded)";
    let e = gs_io::scene::decode_rgb(&p).unwrap_err().to_string();
    assert_has(&e, &["giant.png: cannot read image header", caps]);
    let e = gs_io::scene::decode_rgb_bytes(&png_declaring(1_000_000_000, 1_000_000_000), &p).unwrap_err().to_string();
    assert_has(&e, &["giant.png: cannot read image header", caps]);
    // Sides within the Limits but more pixels than the cap: refused from the header too.
    let e = gs_io::scene::decode_rgb_bytes(&png_declaring(65_536, 65_536), &p).unwrap_err().to_string();
    assert_has(&e, &["giant.png: image 65536x65536 exceeds the cap of 67108864 pixels"]);
    // A real 4 × 4 header in front of a sparse file over the image cap.
    let p = sparse_over(dir.path(), "huge.png", &png_declaring(4, 4), IMAGE);
    over_cap(gs_io::scene::decode_rgb(&p).unwrap_err(), &p, IMAGE);
    let p = sparse_over(dir.path(), "huge.exr", b"v/1\x01", IMAGE);
    over_cap(gs_io::read_exr(&p).unwrap_err(), &p, IMAGE);
    // A device is not an image file.
    let e = gs_io::scene::decode_mask(Path::new("/dev/zero")).unwrap_err().to_string();
    assert_eq!(e, "/dev/zero: not a regular file (an image is read from a file, not a folder, pipe or device)");
    let e = gs_io::scene::decode_rgb(&dir.path().join("none.png")).unwrap_err().to_string();
    assert!(e.ends_with("none.png: missing image file"), "{e}");
}

/// A 16 × 16 baseline JPEG whose SOF0 was rewritten to declare `w2` × `h2`.
fn jpeg_declaring(w2: u16, h2: u16) -> Vec<u8> {
    let img = image::RgbImage::from_pixel(16, 16, image::Rgb([90, 120, 200]));
    let mut v = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut v), image::ImageFormat::Jpeg).unwrap();
    // SOF0: FF C0, length (2), precision (1), then height and width.
    let sof = v.windows(2).position(|w| w == [0xFF, 0xC0]).unwrap();
    v[sof + 5..sof + 7].copy_from_slice(&h2.to_be_bytes());
    v[sof + 7..sof + 9].copy_from_slice(&w2.to_be_bytes());
    v
}

#[test]
fn decompression_bombs_refused_flat_images_kept() {
    // The fuzz find's shape: a JPEG of a few hundred bytes declaring 65519 × 1012 pixels (within
    // the pixel cap) would decode ~1 GB. Refused from its header and its size.
    let bomb = jpeg_declaring(65_519, 1_012);
    assert!(bomb.len() < 1000, "{} bytes", bomb.len());
    let p = Path::new("bomb.jpg");
    let e = gs_io::scene::decode_rgb_bytes(&bomb, p).unwrap_err().to_string();
    let holds = format!("more than a file of {} bytes can hold at any compression", bomb.len());
    assert_has(&e, &["bomb.jpg: image of 65519x1012 needs 189.7 MiB of samples", &holds]);
    let e = gs_io::scene::decode_mask_bytes(&bomb, p).unwrap_err().to_string();
    assert_has(&e, &["bomb.jpg: image of 65519x1012", &holds]);
    // The same from a file on disk, and for a PNG declaring a large size.
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("bomb.jpg");
    std::fs::write(&f, &bomb).unwrap();
    assert_has(&gs_io::scene::decode_rgb(&f).unwrap_err().to_string(), &["bomb.jpg: image of 65519x1012", &holds]);
    let e = gs_io::scene::decode_rgb_bytes(&png_declaring(8_000, 6_000), Path::new("b.png")).unwrap_err().to_string();
    assert_has(&e, &["b.png: image of 8000x6000 needs 137.3 MiB of samples"]);
    // A real flat photo beyond the 32 MiB floor (4000 × 3000 of one colour, 34 MiB of RGB) is
    // far below deflate's ratio and decodes; so does a small flat one of any ratio.
    for (w, h) in [(4000, 3000), (64, 64)] {
        let flat = image::RgbImage::from_pixel(w, h, image::Rgb([255, 255, 255]));
        let mut png = Vec::new();
        flat.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).unwrap();
        let img = gs_io::scene::decode_rgb_bytes(&png, Path::new("flat.png")).unwrap();
        assert_eq!((img.width(), img.height()), (w as usize, h as usize));
        assert!(img.data().iter().all(|&v| v == 1.0));
    }
}

#[test]
fn colmap_binary_and_text() {
    let dir = tempfile::tempdir().unwrap();
    // points3D.bin claiming 10^15 points in 8 bytes.
    let e = gs_io::colmap::parse_points3d_bin(&1_000_000_000_000_000u64.to_le_bytes(), Path::new("m/points3D.bin"))
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "m/points3D.bin: the number of points at byte offset 0 declares 1000000000000000 records of at least 51 bytes each (45.3 PiB), more than the 0 bytes left in the file can hold (truncated, or a wrong count?); the cap for a COLMAP model file is 16 GiB"
    );
    let readers: [(&str, fn(&Path) -> gs_io::Result<gs_io::ColmapModel>); 2] =
        [("cameras.bin", gs_io::colmap::read_binary), ("cameras.txt", gs_io::colmap::read_text)];
    for (name, read) in readers {
        let sub = dir.path().join(name.replace('.', "_"));
        std::fs::create_dir(&sub).unwrap();
        let p = sparse_over(&sub, name, &1u64.to_le_bytes(), COLMAP);
        over_cap(read(&sub).unwrap_err(), &p, COLMAP);
    }
}

#[test]
fn obj_and_npy() {
    let dir = tempfile::tempdir().unwrap();
    let p = sparse_over(dir.path(), "huge.obj", b"v 0 0 0\n", OBJ);
    over_cap(gs_io::read_obj(&p).unwrap_err(), &p, OBJ);
    let p = sparse_over(dir.path(), "huge.npy", b"\x93NUMPY\x01\x00", NPY);
    over_cap(gs_io::read_npy(&p).unwrap_err(), &p, NPY);
    over_cap(gs_io::read_npz(&p).unwrap_err(), &p, NPY);
    // A 10^6 × 10^6 float map declared in a 128-byte file.
    let p = dir.path().join("absurd.npy");
    std::fs::write(&p, npy("<f4", "False", "(1000000, 1000000)", 0)).unwrap();
    let e = gs_io::read_npy(&p).unwrap_err().to_string();
    assert_has(&e, &["absurd.npy: shape [1000000, 1000000] of <f4 declares 1000000000000 values of at least 4 bytes each (3.6 TiB), more than the 0 bytes", "the cap for a NumPy file is 2 GiB"]);
}
