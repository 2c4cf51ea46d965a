// Radix sort, pass 3 of 3 (after the exclusive scan of the histogram): stable scatter of one
// 4-bit digit. Each thread owns 8 consecutive keys; the per-(digit, thread) counts are scanned
// digit-major in workgroup memory, so equal digits keep their input order.

@group(0) @binding(2) var<storage, read> keys_in: array<u32>;
@group(0) @binding(3) var<storage, read> vals_in: array<u32>;
@group(0) @binding(4) var<storage, read> hist: array<u32>;
@group(0) @binding(5) var<storage, read_write> keys_out: array<u32>;
@group(0) @binding(6) var<storage, read_write> vals_out: array<u32>;

var<workgroup> flat: array<u32, 2048>;
var<workgroup> part: array<u32, 128>;

@compute @workgroup_size(128)
fn radix_scatter(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
                 @builtin(local_invocation_index) li: u32) {
    let b = linear_group(wid, nwg);
    if (b >= pass_.nb) {
        return;
    }
    var cnt = array<u32, 16>(0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u);
    for (var k = 0u; k < 8u; k++) {
        let i = b * 1024u + li * 8u + k;
        if (i < pass_.n) {
            let d = (keys_in[i] >> pass_.shift) & 15u;
            cnt[d] += 1u;
        }
    }
    for (var d = 0u; d < 16u; d++) {
        flat[d * 128u + li] = cnt[d];
    }
    workgroupBarrier();
    var s = 0u;
    for (var j = 0u; j < 16u; j++) {
        let v = flat[li * 16u + j];
        flat[li * 16u + j] = s;
        s += v;
    }
    part[li] = s;
    workgroupBarrier();
    for (var off = 1u; off < 128u; off <<= 1u) {
        var x = 0u;
        if (li >= off) {
            x = part[li - off];
        }
        workgroupBarrier();
        part[li] += x;
        workgroupBarrier();
    }
    let excl = part[li] - s;
    for (var j = 0u; j < 16u; j++) {
        flat[li * 16u + j] += excl;
    }
    workgroupBarrier();
    var run: array<u32, 16>;
    for (var d = 0u; d < 16u; d++) {
        run[d] = hist[d * pass_.nb + b] + flat[d * 128u + li] - flat[d * 128u];
    }
    for (var k = 0u; k < 8u; k++) {
        let i = b * 1024u + li * 8u + k;
        if (i < pass_.n) {
            let key = keys_in[i];
            let d = (key >> pass_.shift) & 15u;
            let pos = run[d];
            keys_out[pos] = key;
            vals_out[pos] = vals_in[i];
            run[d] = pos + 1u;
        }
    }
}
