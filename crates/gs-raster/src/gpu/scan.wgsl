// Exclusive prefix sum of u32, in place, 1024 elements per workgroup (256 threads x 4).
// Multi-level: `scan_reduce` writes block totals, the totals are scanned recursively, then
// `scan_apply` scans each block and adds its scanned total (pass_.mode == 1).

@group(0) @binding(2) var<storage, read_write> data: array<u32>;
@group(0) @binding(3) var<storage, read_write> sums: array<u32>;

var<workgroup> part: array<u32, 256>;

@compute @workgroup_size(256)
fn scan_reduce(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
               @builtin(local_invocation_index) li: u32) {
    let b = linear_group(wid, nwg);
    if (b >= pass_.nb) {
        return;
    }
    let base = b * 1024u + li * 4u;
    var s = 0u;
    for (var k = 0u; k < 4u; k++) {
        if (base + k < pass_.n) {
            s += data[base + k];
        }
    }
    part[li] = s;
    workgroupBarrier();
    for (var off = 128u; off > 0u; off >>= 1u) {
        if (li < off) {
            part[li] += part[li + off];
        }
        workgroupBarrier();
    }
    if (li == 0u) {
        sums[b] = part[0];
    }
}

@compute @workgroup_size(256)
fn scan_apply(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
              @builtin(local_invocation_index) li: u32) {
    let b = linear_group(wid, nwg);
    if (b >= pass_.nb) {
        return;
    }
    let base = b * 1024u + li * 4u;
    var v = array<u32, 4>(0u, 0u, 0u, 0u);
    var s = 0u;
    for (var k = 0u; k < 4u; k++) {
        if (base + k < pass_.n) {
            v[k] = data[base + k];
        }
        s += v[k];
    }
    part[li] = s;
    workgroupBarrier();
    for (var off = 1u; off < 256u; off <<= 1u) {
        var x = 0u;
        if (li >= off) {
            x = part[li - off];
        }
        workgroupBarrier();
        part[li] += x;
        workgroupBarrier();
    }
    var run = part[li] - s;
    if (pass_.mode == 1u) {
        run += sums[b];
    }
    for (var k = 0u; k < 4u; k++) {
        if (base + k < pass_.n) {
            data[base + k] = run;
        }
        run += v[k];
    }
}
