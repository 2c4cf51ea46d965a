//! COLMAP parsing (text and binary) of the fox model, and undistortion of a fox image (fox from
//! the shared test data; prints SKIPPED without it).

use criterion::{Criterion, criterion_group, criterion_main};
use gs_io::colmap::{parse_images_bin, read_binary, read_text, write_binary, write_images_bin};
use gs_io::undistort::{UndistortMap, UndistortOptions, undistort_camera};
use std::hint::black_box;
use std::path::Path;

/// fox in the shared test data (`VAGSL_TEST_DATA`, see gs-testdata).
fn fox() -> std::path::PathBuf {
    gs_testdata::root().join("data/fox")
}

fn bench(c: &mut Criterion) {
    if !gs_testdata::needs!("data/fox") {
        return;
    }
    let model = read_text(&fox().join("sparse/0")).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    write_binary(&model, tmp.path()).unwrap();
    let mut images_bin = Vec::new();
    write_images_bin(&model, &mut images_bin).unwrap();

    let mut g = c.benchmark_group("colmap_fox");
    g.sample_size(10);
    g.bench_function("read_text", |b| b.iter(|| black_box(read_text(&fox().join("sparse/0")).unwrap())));
    g.bench_function("read_binary", |b| b.iter(|| black_box(read_binary(tmp.path()).unwrap())));
    g.bench_function("parse_images_bin", |b| {
        b.iter(|| black_box(parse_images_bin(&images_bin, Path::new("images.bin")).unwrap()))
    });
    g.bench_function("mean_reprojection_error", |b| b.iter(|| black_box(model.mean_reprojection_error())));
    let cam = &model.cameras[&1];
    g.bench_function("undistort_camera", |b| {
        b.iter(|| black_box(undistort_camera(cam, &UndistortOptions::default()).unwrap()))
    });
    let pinhole = undistort_camera(cam, &UndistortOptions::default()).unwrap();
    g.bench_function("undistort_map_new", |b| b.iter(|| black_box(UndistortMap::new(cam, &pinhole))));
    let map = UndistortMap::new(cam, &pinhole);
    let image = gs_io::scene::decode_rgb(&fox().join("images/0001.jpg")).unwrap();
    g.bench_function("undistort_map_apply_540x960", |b| b.iter(|| black_box(map.apply(&image).unwrap())));
    g.bench_function("decode_jpeg_540x960", |b| {
        b.iter(|| black_box(gs_io::scene::decode_rgb(&fox().join("images/0001.jpg")).unwrap()))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
