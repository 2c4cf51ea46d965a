// Radix sort, pass 1 of 3: per-block histogram of one 4-bit digit (128 threads x 8 keys =
// 1024 keys per block), written digit-major: hist[digit * nb + block].

@group(0) @binding(2) var<storage, read> keys: array<u32>;
@group(0) @binding(3) var<storage, read_write> hist: array<u32>;

var<workgroup> cnt: array<atomic<u32>, 16>;

@compute @workgroup_size(128)
fn radix_count(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
               @builtin(local_invocation_index) li: u32) {
    let b = linear_group(wid, nwg);
    if (b >= pass_.nb) {
        return;
    }
    for (var k = 0u; k < 8u; k++) {
        let i = b * 1024u + li * 8u + k;
        if (i < pass_.n) {
            atomicAdd(&cnt[(keys[i] >> pass_.shift) & 15u], 1u);
        }
    }
    workgroupBarrier();
    if (li < 16u) {
        hist[li * pass_.nb + b] = atomicLoad(&cnt[li]);
    }
}
