//! Radix sort and prefix scan of 1M u32 on the best adapter (skipped with a message when
//! there is none). `cargo bench -p gs-gpu`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use gs_gpu::{BufferPool, Dispatcher, GpuContext, GpuOptions, RadixSort, ShrinkPolicy};

const N: usize = 1 << 20;

fn bench(c: &mut Criterion) {
    let ctx = match GpuContext::new(&GpuOptions::default()) {
        Ok(ctx) => ctx,
        Err(e) => {
            eprintln!("SKIPPED gs-gpu benches: no wgpu adapter ({e})");
            return;
        }
    };
    eprintln!("wgpu adapter: {}", ctx.description());
    let mut pool = BufferPool::new(&ctx, ShrinkPolicy::default());
    let sort = RadixSort::new(&ctx, &mut pool).expect("kernels");
    let ids: Vec<_> = ["ka", "va", "kb", "vb"]
        .into_iter()
        .map(|l| pool.add_storage(l))
        .collect();
    let disp = Dispatcher::new(&ctx, 16);
    let mut s = 0x2545_F491_4F6C_DD1Du64;
    let keys: Vec<u32> = (0..N)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 32) as u32
        })
        .collect();
    let vals: Vec<u32> = (0..N as u32).collect();
    for &id in &ids {
        pool.ensure(id, N as u64 * 4);
    }
    sort.reserve(&mut pool, N as u64);
    sort.prefix_scan().reserve(&mut pool, N as u64);
    let wait = || ctx.download(pool.buffer(ids[2]), 0, 4).expect("readback");
    let mut g = c.benchmark_group("gs-gpu");
    g.sample_size(10).throughput(Throughput::Elements(N as u64));
    g.bench_function("radix_sort_1M_32bit", |b| {
        b.iter(|| {
            ctx.queue()
                .write_buffer(pool.buffer(ids[0]), 0, bytemuck::cast_slice(&keys));
            ctx.queue()
                .write_buffer(pool.buffer(ids[1]), 0, bytemuck::cast_slice(&vals));
            let mut enc = disp.encoder();
            let a = (pool.whole(ids[0]), pool.whole(ids[1]));
            let bb = (pool.whole(ids[2]), pool.whole(ids[3]));
            sort.encode(&disp, &mut enc, &pool, [a, bb], N as u32, 32)
                .expect("sort");
            disp.submit(enc);
            wait()
        })
    });
    g.bench_function("prefix_scan_1M", |b| {
        b.iter(|| {
            let mut enc = disp.encoder();
            let data = pool.range(ids[2], 0, N as u64 * 4);
            sort.prefix_scan()
                .encode(&disp, &mut enc, &pool, data, N as u32)
                .expect("scan");
            disp.submit(enc);
            wait()
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
