//! Device tests of gs-gpu: prefix scan and radix sort against CPU references, and the buffer
//! pool's growth and shrinking, on whatever adapter exists (Mesa lavapipe in CI).
//!
//! Without any adapter the tests print `SKIPPED` and pass, except in CI (`CI=true`), where a
//! missing adapter is a failure (the convention of gs-raster's tests/wgpu_parity.rs).

use std::borrow::Cow;

use gs_gpu::{
    Arena, Binding, BufferPool, Dispatcher, GpuContext, GpuOptions, Kernel, PassUniform, RadixSort,
    ShrinkPolicy,
};

/// A context on this machine's adapter, or `None` (skip) when there is none locally; panics
/// in CI.
fn context() -> Option<GpuContext> {
    gs_testdata::wgpu_context!(&GpuOptions::default())
}

/// Deterministic pseudo-random u32s (xorshift).
fn random_u32s(n: usize, seed: u64, mask: u32) -> Vec<u32> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 16) as u32 & mask
        })
        .collect()
}

fn upload(ctx: &GpuContext, pool: &mut BufferPool, id: gs_gpu::BufId, data: &[u32]) {
    pool.ensure(id, (data.len() as u64 * 4).max(4));
    ctx.queue()
        .write_buffer(pool.buffer(id), 0, bytemuck::cast_slice(data));
}

fn download(ctx: &GpuContext, pool: &BufferPool, id: gs_gpu::BufId, n: usize) -> Vec<u32> {
    bytemuck::pod_collect_to_vec(&ctx.download(pool.buffer(id), 0, n as u64 * 4).unwrap())
}

#[test]
fn prefix_scan_matches_the_cpu_at_every_level() {
    let Some(ctx) = context() else { return };
    let mut pool = BufferPool::new(&ctx, ShrinkPolicy::default());
    let sort = RadixSort::new(&ctx, &mut pool).unwrap();
    let scan = sort.prefix_scan();
    let data = pool.add_storage("data");
    let disp = Dispatcher::new(&ctx, 16);
    // One block, a partial block, two levels, three levels (> 1024² elements), wrap-around.
    for (n, mask) in [
        (0, 0xff),
        (1, 0xff),
        (1000, 0xff),
        (1025, 0xffff),
        (300_001, 0xff),
        (1_050_000, 7),
        (5000, u32::MAX),
    ] {
        let v = random_u32s(n, n as u64 + 1, mask);
        pool.begin_frame();
        upload(&ctx, &mut pool, data, &v);
        scan.reserve(&mut pool, n as u64);
        let mut enc = disp.encoder();
        scan.encode(
            &disp,
            &mut enc,
            &pool,
            pool.range(data, 0, n as u64 * 4),
            n as u32,
        )
        .unwrap();
        disp.submit(enc);
        let got = download(&ctx, &pool, data, n);
        let mut run = 0u32;
        let want: Vec<u32> = v
            .iter()
            .map(|&x| {
                let r = run;
                run = run.wrapping_add(x);
                r
            })
            .collect();
        assert_eq!(got, want, "scan of {n}");
    }
}

#[test]
fn radix_sort_is_a_stable_sort() {
    let Some(ctx) = context() else { return };
    let mut pool = BufferPool::new(&ctx, ShrinkPolicy::default());
    let sort = RadixSort::new(&ctx, &mut pool).unwrap();
    let ids: Vec<_> = ["ka", "va", "kb", "vb"]
        .into_iter()
        .map(|l| pool.add_storage(l))
        .collect();
    let disp = Dispatcher::new(&ctx, 16);
    // Few distinct keys (stability matters), full 32-bit keys, an odd number of passes.
    for (n, bits, mask) in [
        (1, 32, u32::MAX),
        (3000, 8, 0x0f),
        (70_000, 32, u32::MAX),
        (200_001, 12, 0xfff),
    ] {
        let keys = random_u32s(n, 7 + n as u64, mask);
        let vals: Vec<u32> = (0..n as u32).collect();
        pool.begin_frame();
        upload(&ctx, &mut pool, ids[0], &keys);
        upload(&ctx, &mut pool, ids[1], &vals);
        pool.ensure(ids[2], n as u64 * 4);
        pool.ensure(ids[3], n as u64 * 4);
        sort.reserve(&mut pool, n as u64);
        let mut enc = disp.encoder();
        let a = (pool.whole(ids[0]), pool.whole(ids[1]));
        let b = (pool.whole(ids[2]), pool.whole(ids[3]));
        let in_b = sort
            .encode(&disp, &mut enc, &pool, [a, b], n as u32, bits)
            .unwrap();
        disp.submit(enc);
        assert_eq!(in_b, bits.div_ceil(4) % 2 == 1);
        let (k, v) = if in_b {
            (ids[2], ids[3])
        } else {
            (ids[0], ids[1])
        };
        let (gk, gv) = (download(&ctx, &pool, k, n), download(&ctx, &pool, v, n));
        let mut want: Vec<(u32, u32)> = keys.iter().copied().zip(vals).collect();
        want.sort_by_key(|&(key, _)| key); // stable: ties keep the index order
        let got: Vec<(u32, u32)> = gk.into_iter().zip(gv).collect();
        assert_eq!(got, want, "sort of {n} keys over {bits} bits");
    }
}

#[test]
fn pool_grows_geometrically_and_shrinks_after_the_window() {
    let Some(ctx) = context() else { return };
    let policy = ShrinkPolicy {
        window: 3,
        factor: 4,
    };
    let mut pool = BufferPool::new(&ctx, policy);
    let big = pool.add_storage("big");
    let idle = pool.add_storage("idle");
    pool.begin_frame();
    pool.ensure(big, 1 << 20);
    pool.ensure(idle, 1 << 16);
    assert_eq!(pool.capacity(big), 1 << 20);
    pool.ensure(big, (1 << 20) + 4);
    assert_eq!(pool.capacity(big), 1 << 21, "grows by doubling");
    // Steady, smaller use of `big`; `idle` is never needed again.
    for frame in 0..3 {
        assert_eq!(
            pool.begin_frame(),
            0,
            "frame {frame}: not enough history yet"
        );
        pool.ensure(big, 100_000);
    }
    let before = pool.allocated_bytes();
    let freed = pool.begin_frame();
    assert_eq!(pool.capacity(big), 100_096, "shrunk to the recent need");
    assert_eq!(pool.capacity(idle), 256, "released");
    assert_eq!(freed, before - pool.allocated_bytes());
    // Within the factor nothing moves; the shrunk buffer is still usable by a kernel.
    pool.ensure(big, 60_000);
    assert_eq!(pool.begin_frame(), 0);
    let k = Kernel::new(
        &ctx,
        "fill",
        &["@compute @workgroup_size(256)\nfn fill(ids: Ids) { let i = thread_1d(ids); if (i < pass_.n) { x[i] = i; } }"],
        &[Binding::write("x", "array<u32>")],
    )
    .unwrap();
    let disp = Dispatcher::new(&ctx, 16);
    pool.ensure(big, 4000);
    let mut enc = disp.encoder();
    disp.dispatch_1d(
        &mut enc,
        &k,
        &[pool.whole(big)],
        PassUniform {
            n: 1000,
            ..Default::default()
        },
    )
    .unwrap();
    disp.submit(enc);
    assert_eq!(
        download(&ctx, &pool, big, 1000),
        (0..1000).collect::<Vec<u32>>()
    );
}

#[test]
fn kernel_errors_are_results() {
    let Some(ctx) = context() else { return };
    let err = Kernel::new(&ctx, "broken", &["fn broken( {"], &[]).unwrap_err();
    assert!(matches!(err, gs_gpu::GpuError::Device(_)), "{err}");
}

#[test]
fn unreserved_scratch_is_an_error_before_anything_is_recorded() {
    let Some(ctx) = context() else { return };
    let mut pool = BufferPool::new(&ctx, ShrinkPolicy::default());
    let sort = RadixSort::new(&ctx, &mut pool).unwrap();
    let ids: Vec<_> = ["ka", "va", "kb", "vb"].into_iter().map(|l| pool.add_storage(l)).collect();
    let n = 1u64 << 20;
    for &id in &ids {
        pool.ensure(id, n * 4);
    }
    // Reserved for the sort of 1000 pairs, not for a scan or a sort of 2^20.
    sort.reserve(&mut pool, 1000);
    let disp = Dispatcher::new(&ctx, 16);
    let mut enc = disp.encoder();
    let err = sort
        .prefix_scan()
        .encode(&disp, &mut enc, &pool, pool.whole(ids[0]), n as u32)
        .unwrap_err();
    assert!(
        matches!(err, gs_gpu::GpuError::NotReserved { label: "scan_tmp", .. }),
        "{err}"
    );
    let err = sort
        .encode(&disp, &mut enc, &pool, pairs(&pool, &ids), n as u32, 32)
        .unwrap_err();
    assert!(
        matches!(err, gs_gpu::GpuError::NotReserved { label: "radix_hist", .. }),
        "{err}"
    );
    assert!(err.to_string().contains("reserve"), "{err}");
    // Reserved, both record.
    sort.reserve(&mut pool, n);
    sort.prefix_scan().reserve(&mut pool, n);
    let mut enc = disp.encoder();
    sort.prefix_scan()
        .encode(&disp, &mut enc, &pool, pool.whole(ids[0]), n as u32)
        .unwrap();
    sort.encode(&disp, &mut enc, &pool, pairs(&pool, &ids), n as u32, 32)
        .unwrap();
    disp.submit(enc);
}

/// The (keys, values) ping-pong pairs of four pool buffers.
fn pairs<'a>(p: &'a BufferPool, ids: &[gs_gpu::BufId]) -> [(gs_gpu::Bind<'a>, gs_gpu::Bind<'a>); 2] {
    [(p.whole(ids[0]), p.whole(ids[1])), (p.whole(ids[2]), p.whole(ids[3]))]
}

/// The ledger counts what crosses between host and device, on every clone of a context: the
/// counted writes, each readback the host waits for and its bytes, and each submission.
#[test]
fn the_ledger_counts_writes_readbacks_and_submissions() {
    let Some(ctx) = context() else { return };
    let mut pool = BufferPool::new(&ctx, ShrinkPolicy::default());
    let data = pool.add_storage("data");
    pool.ensure(data, 4000);
    let before = ctx.transfers();
    let clone = ctx.clone();
    clone.write_buffer(pool.buffer(data), 0, &[7u8; 4000]);
    ctx.write_with(pool.buffer(data), 400, |b| b.fill(1));
    let back = ctx.download(pool.buffer(data), 0, 4000).unwrap();
    assert_eq!((back[0], back[399], back[400], back[3999]), (1, 1, 7, 7));
    let d = clone.transfers() - before;
    assert_eq!(d, gs_gpu::Transfers { syncs: 1, bytes_down: 4000, bytes_up: 4400, submits: 1 });
}

/// Readbacks requested together cost one wait: the first read waits for the device, the
/// second finds its bytes there. A readback dropped unread frees its buffer for the next.
#[test]
fn readbacks_requested_together_cost_one_wait() {
    let Some(ctx) = context() else { return };
    let mut pool = BufferPool::new(&ctx, ShrinkPolicy::default());
    let data = pool.add_storage("data");
    let stage = [pool.add_staging("first"), pool.add_staging("second")];
    pool.ensure(data, 64);
    for s in stage {
        pool.ensure(s, 64);
    }
    ctx.write_buffer(pool.buffer(data), 0, bytemuck::cast_slice(&[5u32; 16]));
    let copy_all = || {
        let mut enc = ctx.device().create_command_encoder(&Default::default());
        for s in stage {
            enc.copy_buffer_to_buffer(pool.buffer(data), 0, pool.buffer(s), 0, 64);
        }
        ctx.queue().submit(Some(enc.finish()));
    };
    copy_all();
    let before = ctx.transfers();
    let (a, b) = (ctx.request_read(pool.buffer(stage[0]), 64), ctx.request_read(pool.buffer(stage[1]), 32));
    let first: Vec<u32> = ctx.finish_read(a, bytemuck::pod_collect_to_vec).unwrap();
    let second: Vec<u32> = ctx.finish_read(b, bytemuck::pod_collect_to_vec).unwrap();
    assert_eq!((first, second), (vec![5; 16], vec![5; 8]));
    let d = ctx.transfers() - before;
    assert_eq!((d.syncs, d.bytes_down), (1, 96), "one wait for both readbacks");
    // Dropped unread: the buffer maps again.
    copy_all();
    drop(ctx.request_read(pool.buffer(stage[0]), 64));
    assert_eq!(ctx.read_buffer(pool.buffer(stage[0]), 8).unwrap(), bytemuck::cast_slice::<u32, u8>(&[5, 5]));
}

fn read_arena(ctx: &GpuContext, arena: &Arena, offset: u32, floats: usize) -> Vec<f32> {
    let bytes = ctx.download(arena.buffer(), 4 * offset as u64, 4 * floats as u64).unwrap();
    bytemuck::pod_collect_to_vec(&bytes)
}

/// Keyed arrays are uploaded once and found again; unkeyed ones every call; a full arena
/// evicts the least recently used array and uploads it again when asked.
#[test]
fn arena_keeps_keyed_arrays_and_evicts_the_least_recently_used() {
    let Some(ctx) = context() else { return };
    // Three slots of four floats.
    let mut arena = Arena::new(&ctx, "test arena", 48);
    let data = |v: f32| vec![v; 4];
    let written = || ctx.transfers().bytes_up;
    let before = written();
    let first = arena.place(&ctx, &[(Some((1, 0)), 4), (None, 4)], |i| Cow::Owned(data(i as f32 + 1.0))).unwrap();
    assert_eq!(written() - before, 32, "both arrays uploaded");
    assert_eq!(read_arena(&ctx, &arena, first[0], 4), data(1.0));
    assert_eq!(read_arena(&ctx, &arena, first[1], 4), data(2.0));
    let before = written();
    let again = arena.place(&ctx, &[(Some((1, 0)), 4), (None, 4)], |i| Cow::Owned(data(i as f32 + 5.0))).unwrap();
    assert_eq!(written() - before, 16, "the keyed array is held, the unkeyed one uploaded");
    assert_eq!(again[0], first[0]);
    assert_eq!(read_arena(&ctx, &arena, again[0], 4), data(1.0));
    assert_eq!(read_arena(&ctx, &arena, again[1], 4), data(6.0));
    // Keys 2 and 3 take the free slot and the unkeyed ones' (those go first); key 1 is then
    // used after them, so key 4 evicts key 2, which comes back on its next use.
    arena.place(&ctx, &[(Some((2, 0)), 4)], |_| Cow::Owned(data(20.0))).unwrap();
    arena.place(&ctx, &[(Some((3, 0)), 4)], |_| Cow::Owned(data(30.0))).unwrap();
    arena.place(&ctx, &[(Some((1, 0)), 4)], |_| panic!("key 1 is held")).unwrap();
    let four = arena.place(&ctx, &[(Some((4, 0)), 4)], |_| Cow::Owned(data(40.0))).unwrap();
    assert_eq!(read_arena(&ctx, &arena, four[0], 4), data(40.0));
    let before = written();
    let two = arena.place(&ctx, &[(Some((2, 0)), 4)], |_| Cow::Owned(data(20.0))).unwrap();
    assert_eq!(written() - before, 16, "key 2 was evicted and comes back");
    assert_eq!(read_arena(&ctx, &arena, two[0], 4), data(20.0));
    // Another part of one key is another array; a call needing more slots than fit fails.
    let parts = arena.place(&ctx, &[(Some((2, 0)), 4), (Some((2, 1)), 4)], |_| Cow::Owned(data(21.0))).unwrap();
    assert_ne!(parts[0], parts[1]);
    assert_eq!(read_arena(&ctx, &arena, parts[0], 4), data(20.0));
    assert!(arena.place(&ctx, &[(None, 4), (None, 4), (None, 4), (None, 4)], |_| Cow::Owned(data(0.0))).is_none());
}

/// A key placed by version keeps one slot: the same version is held, a new one goes up into
/// that slot (the arena never fills with a view's older contents); a version list of another
/// length is refused.
#[test]
fn arena_replaces_a_keys_older_version_in_place() {
    let Some(ctx) = context() else { return };
    let mut arena = Arena::new(&ctx, "test arena", 64 * 16);
    let data = |v: f32| vec![v; 4];
    let first = arena.place_versions(&ctx, &[(Some((5, 1)), 4)], &[10], |_| Cow::Owned(data(1.0))).unwrap();
    let before = ctx.transfers().bytes_up;
    let held = arena.place_versions(&ctx, &[(Some((5, 1)), 4)], &[10], |_| panic!("version 10 is held")).unwrap();
    assert_eq!((held[0], ctx.transfers().bytes_up - before), (first[0], 0));
    for version in 11..40u64 {
        let at = arena.place_versions(&ctx, &[(Some((5, 1)), 4)], &[version], |_| Cow::Owned(data(version as f32))).unwrap();
        assert_eq!(at[0], first[0], "version {version} replaces the last in its slot");
        assert_eq!(read_arena(&ctx, &arena, at[0], 4), data(version as f32));
    }
    assert_eq!(arena.buffer().size(), 8 * 16, "still the first eight slots");
    assert!(arena.place_versions(&ctx, &[(Some((5, 1)), 4)], &[], |_| Cow::Owned(data(0.0))).is_none());
}

/// An arena starts small and doubles when full, keeping what it holds (copied on the device,
/// nothing uploaded again), until its budget; larger arrays start it again.
#[test]
fn arena_grows_and_keeps_its_arrays() {
    let Some(ctx) = context() else { return };
    let mut arena = Arena::new(&ctx, "test arena", 64 * 16);
    let data = |k: u64| vec![k as f32; 4];
    let mut at = Vec::new();
    for k in 0..20u64 {
        let before = ctx.transfers().bytes_up;
        at.push(arena.place(&ctx, &[(Some((k, 0)), 4)], |_| Cow::Owned(data(k))).unwrap()[0]);
        assert_eq!(ctx.transfers().bytes_up - before, 16, "key {k}: only its own array goes up");
    }
    assert!(arena.buffer().size() < 64 * 16, "grown as needed (to {} bytes), not to the budget", arena.buffer().size());
    for k in 0..20u64 {
        let again = arena.place(&ctx, &[(Some((k, 0)), 4)], |_| panic!("key {k} is held")).unwrap()[0];
        assert_eq!(again, at[k as usize]);
        assert_eq!(read_arena(&ctx, &arena, again, 4), data(k), "key {k} after the growth");
    }
    // Arrays twice as long: new slots, the old arrays uploaded again when asked.
    let long = arena.place(&ctx, &[(Some((1, 0)), 8)], |_| Cow::Owned(vec![7.0; 8])).unwrap();
    assert_eq!(read_arena(&ctx, &arena, long[0], 8), vec![7.0; 8]);
    let before = ctx.transfers().bytes_up;
    arena.place(&ctx, &[(Some((2, 0)), 4)], |_| Cow::Owned(data(2))).unwrap();
    assert_eq!(ctx.transfers().bytes_up - before, 16);
}

/// A slot filled on the device is held under its key and version like an upload: found again
/// without an upload, replaced by a new version in place, and read back with others at one
/// wait; what is not held reads back as nothing. The capacity bounds the keys that are never
/// evicted.
#[test]
fn arena_holds_what_the_device_filled() {
    let Some(ctx) = context() else { return };
    let mut arena = Arena::new(&ctx, "test arena", 64 * 16);
    assert_eq!(arena.capacity(&ctx, 4), 64, "a 1 KiB budget holds 64 arrays of 4 floats");
    let uploaded = arena.place_versions(&ctx, &[(Some((1, 0)), 4)], &[3], |_| Cow::Owned(vec![1.0; 4])).unwrap()[0];
    let filled = arena.place_filled(&ctx, (2, 1), 4, 7).unwrap();
    assert_ne!(filled, uploaded);
    // The caller's fill: a device-side copy from another buffer.
    let src = ctx.device().create_buffer(&wgpu::BufferDescriptor { label: None, size: 16, usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST, mapped_at_creation: false });
    ctx.write_buffer(&src, 0, bytemuck::cast_slice(&[5.0f32, 6.0, 7.0, 8.0]));
    let mut enc = ctx.device().create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
    enc.copy_buffer_to_buffer(&src, 0, arena.buffer(), 4 * filled as u64, 16);
    ctx.queue().submit(Some(enc.finish()));
    assert!(arena.holds((2, 1), 4, 7) && !arena.holds((2, 1), 4, 8) && !arena.holds((2, 1), 8, 7));
    let before = ctx.transfers();
    let again = arena.place_versions(&ctx, &[(Some((2, 1)), 4)], &[7], |_| panic!("version 7 is held")).unwrap()[0];
    assert_eq!((again, ctx.transfers().bytes_up - before.bytes_up), (filled, 0));
    let read = arena.read_held(&ctx, &[((2, 1), 4, 7), ((9, 0), 4, 0), ((1, 0), 4, 3), ((1, 0), 4, 4)]).unwrap();
    assert_eq!(read, vec![Some(vec![5.0, 6.0, 7.0, 8.0]), None, Some(vec![1.0; 4]), None]);
    assert_eq!(ctx.transfers().syncs - before.syncs, 1, "one wait for both arrays");
    // A new version filled again takes the key's own slot.
    assert_eq!(arena.place_filled(&ctx, (2, 1), 4, 9), Some(filled));
    assert!(arena.holds((2, 1), 4, 9) && !arena.holds((2, 1), 4, 7));
    assert_eq!(arena.read_held(&ctx, &[((5, 5), 4, 0)]).unwrap(), vec![None]);
    // A forgotten key is held no more, at any version.
    arena.forget((2, 1));
    assert!(!arena.holds((2, 1), 4, 9) && arena.holds((1, 0), 4, 3));
}

/// The prelude's compensated sums, one thread adding values in order, against the exact sum:
/// where f32 drops the small values beside a large one, `kahan_add` and `wide_add` keep them
/// (the dispatcher's `unit` keeps the compiler from cancelling their error terms); over random
/// values of every size the pair stays within 2^-44 of the sum of magnitudes.
#[test]
fn wide_sums_keep_what_f32_drops() {
    let Some(ctx) = context() else { return };
    let mut pool = BufferPool::new(&ctx, ShrinkPolicy::default());
    let (values, out) = (pool.add_storage("values"), pool.add_storage("sums"));
    let src = "@compute @workgroup_size(256)\nfn sum(ids: Ids) { if (thread_1d(ids) != 0u) { return; } \
        var w = vec2<f32>(0.0); var k = vec2<f32>(0.0); var f = 0.0; \
        for (var i = 0u; i < pass_.n; i++) { w = wide_add(w, x[i]); k = kahan_add(k, x[i]); f += x[i]; } \
        sums[0] = w.x; sums[1] = w.y; sums[2] = k.x; sums[3] = f; }";
    let k = Kernel::new(&ctx, "sum", &[src], &[Binding::read("x", "array<f32>"), Binding::write("sums", "array<f32>")]).unwrap();
    let disp = Dispatcher::new(&ctx, 16);
    let mut big_then_ones = vec![1.0e8f32];
    big_then_ones.extend(std::iter::repeat_n(1.0f32, 4000));
    let random: Vec<f32> = random_u32s(5000, 9, u32::MAX)
        .into_iter()
        .map(|b| {
            let (m, e) = ((b & 0xffff) as f32 / 65536.0 - 0.5, ((b >> 16) % 40) as i32 - 20);
            m * 2f32.powi(e)
        })
        .collect();
    for (case, v) in [("1e8 then 4000 ones", big_then_ones), ("random", random)] {
        let bits: Vec<u32> = v.iter().map(|x| x.to_bits()).collect();
        upload(&ctx, &mut pool, values, &bits);
        pool.ensure(out, 16);
        let mut enc = disp.encoder();
        disp.dispatch_1d(&mut enc, &k, &[pool.whole(values), pool.whole(out)], PassUniform { n: v.len() as u32, ..Default::default() }).unwrap();
        disp.submit(enc);
        let got: Vec<f32> = download(&ctx, &pool, out, 4).into_iter().map(f32::from_bits).collect();
        let exact: f64 = v.iter().map(|&x| x as f64).sum();
        let size: f64 = v.iter().map(|&x| (x as f64).abs()).sum();
        let wide = gs_gpu::wide_value([got[0], got[1]]);
        eprintln!("{case}: exact {exact:e}, wide {wide:e}, kahan {:e}, f32 {:e}", got[2], got[3]);
        assert!((wide - exact).abs() <= size * 2f64.powi(-44), "{case}: {wide} against {exact}");
        if case.starts_with("1e8") {
            assert_eq!((wide, got[2] as f64), (exact, exact), "every one kept, by the pair and by the compensation");
            assert_ne!(got[3] as f64, exact, "f32 alone drops them");
        }
    }
}
