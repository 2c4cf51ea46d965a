//! Forward / backward throughput of the CPU rasterizer at 640×480 (`GS_RASTER_BENCH_SIZE=WxH`
//! for another size) with 10k / 100k / 500k
//! Gaussians of a trained-like distribution (small flat anisotropic Gaussians on the surfaces
//! of spheres and a ground plane, screen radius ≈ 2–10 px, mostly opaque), plus the naive
//! per-pixel reference on a reduced case for the speed ratio.
//!
//! Throughput is reported in Gaussian-pixel pairs: `RenderStats::forward_pairs` (per pixel,
//! the tile-list entries it went through before saturating) and `backward_pairs` (entries up
//! to its last contributor). the workspace `BENCHMARKS.md` records measured numbers.
//!
//! With the `wgpu` feature (default) the same scenes also run on the wgpu backend
//! (`raster_wgpu_WxH`, skipped with a message when there is no adapter). On a machine
//! without a GPU that adapter is Mesa's lavapipe (software Vulkan on the CPU): those figures
//! measure the kernels' CPU emulation, not GPU speed. `GS_RASTER_WGPU_REPORT=1` prints plain
//! wall-clock timings (5 calls) instead of running criterion on the wgpu cases.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use gs_core::gaussians::{inverse_sigmoid, rgb_to_sh_dc};
use gs_core::glam::{DVec3, Quat, Vec3};
use gs_core::{Camera, Gaussians, Image, Intrinsics, Rng};
use gs_raster::{OutputGradients, RasterConfig, RenderRequest, backward, render, render_naive};

/// Trained-like synthetic scene: `n` flat Gaussians on three spheres and a ground plane.
fn scene(n: usize, seed: u64) -> Gaussians {
    let mut rng = Rng::new(seed);
    let mut g = Gaussians::with_len(0).unwrap();
    g.sh_degree = 3;
    let spheres = [
        (Vec3::new(0.0, 0.0, 0.0), 1.0f32),
        (Vec3::new(-1.6, 0.4, 0.8), 0.6),
        (Vec3::new(1.5, 0.3, 0.5), 0.7),
    ];
    // Surface areas decide how many Gaussians each surface gets; a surface element of area
    // A/n has radius ≈ sqrt(A/(π n)), which sets the scale (Gaussians overlap ~2×).
    let plane_area = 8.0 * 8.0;
    let areas: Vec<f32> = spheres
        .iter()
        .map(|s| 4.0 * std::f32::consts::PI * s.1 * s.1)
        .collect();
    let total_area: f32 = areas.iter().sum::<f32>() + plane_area;
    let base_scale = (total_area / (std::f32::consts::PI * n as f32)).sqrt() * 1.4;
    while g.len() < n {
        let pick = rng.uniform() * total_area;
        let (p, normal) = if pick < plane_area {
            (
                Vec3::new(
                    rng.uniform_range(-4.0, 4.0),
                    1.0,
                    rng.uniform_range(-4.0, 4.0),
                ),
                Vec3::new(0.0, -1.0, 0.0),
            )
        } else {
            let mut acc = plane_area;
            let mut k = 0;
            for (i, a) in areas.iter().enumerate() {
                acc += a;
                if pick < acc {
                    k = i;
                    break;
                }
            }
            let d = Vec3::new(rng.normal(), rng.normal(), rng.normal()).normalize_or(Vec3::Z);
            (spheres[k].0 + d * spheres[k].1, d)
        };
        // Rotation taking local z to the surface normal, with a random spin about it.
        let q = Quat::from_rotation_arc(Vec3::Z, normal)
            * Quat::from_rotation_z(rng.uniform_range(0.0, std::f32::consts::TAU));
        let s = base_scale * rng.uniform_range(0.5, 1.5);
        let ls = [
            s.ln(),
            (s * rng.uniform_range(0.4, 1.0)).ln(),
            (s * 0.05).ln(),
        ];
        let o = if rng.uniform() < 0.7 {
            rng.uniform_range(0.8, 0.99)
        } else {
            rng.uniform_range(0.05, 0.8)
        };
        let mut sh = [[0.0f32; 3]; 16];
        let base = [
            0.5 + 0.4 * p.x.sin(),
            0.5 + 0.4 * (p.y * 3.0).cos(),
            0.5 + 0.4 * (p.z * 2.0).sin(),
        ];
        sh[0] = base.map(rgb_to_sh_dc);
        for c in sh.iter_mut().skip(1) {
            *c = [
                0.05 * rng.normal(),
                0.05 * rng.normal(),
                0.05 * rng.normal(),
            ];
        }
        g.push(
            p.to_array(),
            ls,
            [q.w, q.x, q.y, q.z],
            inverse_sigmoid(o),
            sh,
        );
    }
    g
}

fn camera(w: u32, h: u32) -> Camera {
    let f = 0.8 * w as f64;
    Camera::look_at(
        w,
        h,
        Intrinsics::new(f, f, w as f64 * 0.5, h as f64 * 0.5),
        DVec3::new(0.5, -1.2, -4.5),
        DVec3::new(0.0, 0.2, 0.0),
        DVec3::new(0.0, -1.0, 0.0),
    )
    .unwrap()
}

/// The image size: `GS_RASTER_BENCH_SIZE=WxH` (e.g. `1920x1080`, as `scripts/gpu-check.sh`
/// asks), else 640×480, the size of the recorded CPU figures.
fn bench_size() -> (u32, u32) {
    let parsed = std::env::var("GS_RASTER_BENCH_SIZE").ok().and_then(|v| {
        let (w, h) = v.split_once('x')?;
        Some((w.trim().parse().ok()?, h.trim().parse().ok()?))
    });
    match parsed {
        Some((w, h)) if (16..=8192).contains(&w) && (16..=8192).contains(&h) => (w, h),
        Some(_) => panic!("GS_RASTER_BENCH_SIZE must be WxH with sides in 16..=8192"),
        None => (640, 480),
    }
}

/// The blends' tile split: `GS_RASTER_TILE_SPLIT=F,B` (forward and backward threads per tile,
/// as `scripts/gpu-check.sh` compares them), else the adapter's own.
fn tile_split() -> Option<gs_raster::TileSplit> {
    let v = std::env::var("GS_RASTER_TILE_SPLIT").ok()?;
    let parsed = v.split_once(',').and_then(|(f, b)| Some((f.trim().parse().ok()?, b.trim().parse().ok()?)));
    let Some((forward_threads, backward_threads)) = parsed else {
        panic!("GS_RASTER_TILE_SPLIT must be F,B (threads per tile of the forward and the backward blend)")
    };
    Some(gs_raster::TileSplit { forward_threads, backward_threads })
}

/// Process CPU time (user + system) in seconds, from /proc/self/stat (Linux; 0 elsewhere).
/// The bench machine is shared, so wall time overstates the cost; CPU time does not.
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    let Some(rest) = stat.rsplit(')').next() else {
        return 0.0;
    };
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11).and_then(|v| v.parse().ok()).unwrap_or(0.0)
        + f.get(12).and_then(|v| v.parse().ok()).unwrap_or(0.0);
    ticks / 100.0
}

/// Runs `f` `iters` times; prints wall and CPU milliseconds per call and pairs per CPU-second.
fn cpu_report(name: &str, pairs: u64, iters: usize, mut f: impl FnMut()) {
    let (w0, c0) = (std::time::Instant::now(), cpu_seconds());
    for _ in 0..iters {
        f();
    }
    let wall = w0.elapsed().as_secs_f64() / iters as f64;
    let cpu = (cpu_seconds() - c0) / iters as f64;
    eprintln!(
        "{name}: wall {:.1} ms, CPU {:.1} ms/call, {:.0} M pairs per CPU-second, {:.0} M pairs/s wall",
        wall * 1e3,
        cpu * 1e3,
        pairs as f64 / cpu.max(1e-9) / 1e6,
        pairs as f64 / wall / 1e6
    );
}

fn bench(c: &mut Criterion) {
    let threads: usize = std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let cfg = RasterConfig::default();
    let (w, h) = bench_size();
    let cam = camera(w, h);
    let counts: Vec<usize> = std::env::var("GS_RASTER_BENCH_COUNTS")
        .ok()
        .map(|v| v.split(',').filter_map(|s| s.trim().parse().ok()).collect())
        .unwrap_or_else(|| vec![10_000, 100_000, 500_000]);
    // Training-like request: colour + alpha + plane depth (+ normal/distance implied).
    let req = RenderRequest {
        color: true,
        alpha: true,
        normal: true,
        distance: true,
        plane_depth: true,
        ..RenderRequest::default()
    };
    let req_color = RenderRequest::default();
    let mut group = c.benchmark_group(format!("raster_{w}x{h}"));
    group.sample_size(10);
    for &n in &counts {
        let g = scene(n, 7);
        let out = pool.install(|| render(&g, &cam, &req, &cfg).unwrap());
        let st = out.stats;
        eprintln!(
            "n={n}: visible {}, intersections {}, forward pairs {} ({:.1}/px), backward pairs {}, box pairs {}, threads {threads}",
            st.visible,
            st.intersections,
            st.forward_pairs,
            st.forward_pairs as f64 / (w * h) as f64,
            st.backward_pairs,
            st.box_pairs
        );
        if std::env::var("GS_RASTER_CPU_REPORT").is_ok() {
            let gc = Image::filled(w as usize, h as usize, 3, 0.01).unwrap();
            let g1 = Image::filled(w as usize, h as usize, 1, 0.01).unwrap();
            let og = OutputGradients {
                color: Some(&gc),
                alpha: Some(&g1),
                plane_depth: Some(&g1),
                normal: Some(&gc),
                ..Default::default()
            };
            let ogc = OutputGradients {
                color: Some(&gc),
                ..Default::default()
            };
            pool.install(|| {
                cpu_report(
                    &format!("n={n} forward_color"),
                    st.forward_pairs,
                    10,
                    || drop(render(&g, &cam, &req_color, &cfg).unwrap()),
                );
                cpu_report(
                    &format!("n={n} forward_geometry"),
                    st.forward_pairs,
                    10,
                    || drop(render(&g, &cam, &req, &cfg).unwrap()),
                );
                cpu_report(
                    &format!("n={n} backward_color"),
                    st.backward_pairs,
                    10,
                    || drop(backward(&g, &cam, &cfg, &out, &ogc).unwrap()),
                );
                cpu_report(
                    &format!("n={n} backward_geometry"),
                    st.backward_pairs,
                    10,
                    || drop(backward(&g, &cam, &cfg, &out, &og).unwrap()),
                );
            });
        }
        group.throughput(Throughput::Elements(st.forward_pairs));
        group.bench_function(BenchmarkId::new("forward_color", n), |b| {
            b.iter(|| pool.install(|| render(&g, &cam, &req_color, &cfg).unwrap()))
        });
        group.bench_function(BenchmarkId::new("forward_geometry", n), |b| {
            b.iter(|| pool.install(|| render(&g, &cam, &req, &cfg).unwrap()))
        });
        let gc = Image::filled(w as usize, h as usize, 3, 0.01).unwrap();
        let g1 = Image::filled(w as usize, h as usize, 1, 0.01).unwrap();
        let og = OutputGradients {
            color: Some(&gc),
            alpha: Some(&g1),
            plane_depth: Some(&g1),
            normal: Some(&gc),
            ..Default::default()
        };
        group.throughput(Throughput::Elements(st.backward_pairs));
        group.bench_function(BenchmarkId::new("backward_geometry", n), |b| {
            b.iter(|| pool.install(|| backward(&g, &cam, &cfg, &out, &og).unwrap()))
        });
        let ogc = OutputGradients {
            color: Some(&gc),
            ..Default::default()
        };
        group.bench_function(BenchmarkId::new("backward_color", n), |b| {
            b.iter(|| pool.install(|| backward(&g, &cam, &cfg, &out, &ogc).unwrap()))
        });
    }
    group.finish();

    #[cfg(feature = "wgpu")]
    bench_wgpu(c, &counts, &cam, &req, &req_color, &cfg);

    // Naive single-threaded reference vs the tiled path on the same reduced case (the naive
    // path is O(pixels × Gaussians)).
    let mut naive = c.benchmark_group("naive_ratio_160x120_10k");
    naive.sample_size(10);
    let cam_s = camera(160, 120);
    let g = scene(10_000, 7);
    let single = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    naive.bench_function("naive_1_thread", |b| {
        b.iter(|| single.install(|| render_naive(&g, &cam_s, &req_color, &cfg).unwrap()))
    });
    naive.bench_function("tiled_1_thread", |b| {
        b.iter(|| single.install(|| render(&g, &cam_s, &req_color, &cfg).unwrap()))
    });
    naive.bench_function("tiled_2_threads", |b| {
        b.iter(|| pool.install(|| render(&g, &cam_s, &req_color, &cfg).unwrap()))
    });
    naive.finish();
}

/// The wgpu backend on the same scenes and requests.
#[cfg(feature = "wgpu")]
fn bench_wgpu(
    c: &mut Criterion,
    counts: &[usize],
    cam: &Camera,
    req: &RenderRequest,
    req_color: &RenderRequest,
    cfg: &RasterConfig,
) {
    let opts = gs_raster::WgpuOptions { tile_split: tile_split(), ..Default::default() };
    let mut r = match gs_raster::WgpuRasterizer::with_options(opts) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("wgpu benches skipped: {e}");
            return;
        }
    };
    let software = if r.is_software() {
        " — software Vulkan on the CPU, not GPU speed"
    } else {
        ""
    };
    eprintln!("wgpu adapter: {}{software}; tile split {:?}", r.adapter_description(), r.tile_split());
    let (w, h) = (cam.width as usize, cam.height as usize);
    let gc = Image::filled(w, h, 3, 0.01).unwrap();
    let g1 = Image::filled(w, h, 1, 0.01).unwrap();
    let og = OutputGradients {
        color: Some(&gc),
        alpha: Some(&g1),
        plane_depth: Some(&g1),
        normal: Some(&gc),
        ..Default::default()
    };
    let ogc = OutputGradients {
        color: Some(&gc),
        ..Default::default()
    };
    let report = std::env::var("GS_RASTER_WGPU_REPORT").is_ok();
    let mut group = c.benchmark_group(format!("raster_wgpu_{w}x{h}"));
    group.sample_size(10);
    for &n in counts {
        let g = scene(n, 7);
        let out = r.render(&g, cam, req, cfg).unwrap();
        let st = out.stats;
        let time = |name: &str, pairs: u64, f: &mut dyn FnMut()| {
            f(); // warm-up (buffer growth, pipeline caches)
            let t0 = std::time::Instant::now();
            for _ in 0..5 {
                f();
            }
            let dt = t0.elapsed().as_secs_f64() / 5.0;
            eprintln!(
                "wgpu n={n} {name}: {:.1} ms/call, {:.0} M pairs/s",
                dt * 1e3,
                pairs as f64 / dt / 1e6
            );
        };
        if report {
            time("forward_color", st.forward_pairs, &mut || {
                drop(r.render(&g, cam, req_color, cfg).unwrap())
            });
            time("forward_geometry", st.forward_pairs, &mut || {
                drop(r.render(&g, cam, req, cfg).unwrap())
            });
            // A backward needs the latest render of the rasterizer: render + backward.
            time("forward_geometry+backward_color", st.backward_pairs, &mut || {
                let o = r.render(&g, cam, req, cfg).unwrap();
                drop(r.backward(&g, cam, cfg, &o, &ogc).unwrap())
            });
            time("forward_geometry+backward_geometry", st.backward_pairs, &mut || {
                let o = r.render(&g, cam, req, cfg).unwrap();
                drop(r.backward(&g, cam, cfg, &o, &og).unwrap())
            });
            // Where the last call's time went (host clock): uploads, device, unpacking.
            print_timings(n, "", r.timings());
            // One training step (render, geometry backward, Adam): the parameters uploaded and
            // the gradients read back for the host's Adam, against the resident model with
            // Adam and the densification statistics on the device (only a 4-byte flag comes back).
            let (mut gh, mut adam) = (g.clone(), optimiser(&g));
            time("train_step_host_adam", st.backward_pairs, &mut || {
                let o = r.render(&gh, cam, req, cfg).unwrap();
                let grads = r.backward(&gh, cam, cfg, &o, &og).unwrap();
                gs_raster::adam_step(&mut adam, &mut gh, &grads).unwrap();
            });
            let (gd, mut adam) = (g.clone(), optimiser(&g));
            r.make_resident(&gd, &adam, &gs_core::DensifyStats::new(gd.len())).unwrap();
            time("train_step_resident", st.backward_pairs, &mut || {
                let o = r.render(&gd, cam, req, cfg).unwrap();
                let extras = gs_raster::StepExtras { accumulate: Some(1.0), ..Default::default() };
                r.backward_and_step(&gd, cam, cfg, &o, &og, &mut adam, extras).unwrap();
            });
            print_timings(n, "resident ", r.timings());
            r.release_resident();
            continue;
        }
        group.throughput(Throughput::Elements(st.forward_pairs));
        group.bench_function(BenchmarkId::new("forward_color", n), |b| {
            b.iter(|| r.render(&g, cam, req_color, cfg).unwrap())
        });
        group.bench_function(BenchmarkId::new("forward_geometry", n), |b| {
            b.iter(|| r.render(&g, cam, req, cfg).unwrap())
        });
        let out = r.render(&g, cam, req, cfg).unwrap();
        group.throughput(Throughput::Elements(st.backward_pairs));
        group.bench_function(BenchmarkId::new("backward_geometry", n), |b| {
            b.iter(|| r.backward(&g, cam, cfg, &out, &og).unwrap())
        });
        group.bench_function(BenchmarkId::new("backward_color", n), |b| {
            b.iter(|| r.backward(&g, cam, cfg, &out, &ogc).unwrap())
        });
    }
    group.finish();
}

/// Prints where the latest render and backward of `n` Gaussians spent their time.
#[cfg(feature = "wgpu")]
fn print_timings(n: usize, label: &str, t: gs_raster::CallTimings) {
    for (name, p) in [("render", t.render), ("backward", t.backward)] {
        eprintln!(
            "wgpu n={n} last {label}{name}: upload {:.1} ms, device {:.1} ms, unpack {:.1} ms",
            p.upload.as_secs_f64() * 1e3,
            p.device.as_secs_f64() * 1e3,
            p.unpack.as_secs_f64() * 1e3
        );
    }
}

/// Adam with one group per parameter of `g` (gs-train's learning rates do not matter here).
#[cfg(feature = "wgpu")]
fn optimiser(g: &Gaussians) -> gs_core::Adam {
    let mut adam = gs_core::Adam::new(gs_core::AdamConfig::default());
    for p in gs_core::Param::ALL {
        adam.add_group(p.name(), 1e-4, g.len(), p.row_width()).unwrap();
    }
    adam
}

criterion_group!(benches, bench);
criterion_main!(benches);
