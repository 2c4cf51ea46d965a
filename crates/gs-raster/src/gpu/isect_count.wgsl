// Tile intersections per depth-sorted Gaussian (0 for culled ones, which sort last), and the
// exact 64-bit total in counters[2] (low) / counters[3] (high).

@group(0) @binding(2) var<storage, read> keys: array<u32>;
@group(0) @binding(3) var<storage, read> vals: array<u32>;
@group(0) @binding(4) var<storage, read> proj: array<u32>;
@group(0) @binding(5) var<storage, read_write> counts: array<u32>;
@group(0) @binding(6) var<storage, read_write> counters: array<atomic<u32>>;

@compute @workgroup_size(256)
fn isect_count(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
               @builtin(local_invocation_index) li: u32) {
    let k = linear_group(wid, nwg) * 256u + li;
    if (k >= pass_.n) {
        return;
    }
    if (keys[k] == INVISIBLE) {
        counts[k] = 0u;
        return;
    }
    let o = vals[k] * 5u;
    let area = (proj[o + 2u] - proj[o]) * (proj[o + 3u] - proj[o + 1u]);
    counts[k] = area;
    let old = atomicAdd(&counters[2], area);
    if (old + area < old) {
        atomicAdd(&counters[3], 1u);
    }
}
