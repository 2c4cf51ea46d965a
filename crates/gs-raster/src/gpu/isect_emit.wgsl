// Writes the (tile, Gaussian) pairs of each depth-sorted Gaussian at its scanned offset, so
// that a stable sort by tile keeps every tile list in (depth, index) order.

@group(0) @binding(2) var<storage, read> keys: array<u32>;
@group(0) @binding(3) var<storage, read> vals: array<u32>;
@group(0) @binding(4) var<storage, read> proj: array<u32>;
@group(0) @binding(5) var<storage, read> offsets: array<u32>;
@group(0) @binding(6) var<storage, read_write> tile_keys: array<u32>;
@group(0) @binding(7) var<storage, read_write> tile_vals: array<u32>;

@compute @workgroup_size(256)
fn isect_emit(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
              @builtin(local_invocation_index) li: u32) {
    let k = linear_group(wid, nwg) * 256u + li;
    if (k >= pass_.n || keys[k] == INVISIBLE) {
        return;
    }
    let gid = vals[k];
    let r = gid * 5u;
    let x0 = proj[r];
    let y0 = proj[r + 1u];
    let rw = proj[r + 2u] - x0;
    let area = rw * (proj[r + 3u] - y0);
    // Rectangle entries [pass_.shift, pass_.nb) in row-major order (one dispatch per window
    // of 32768 entries: llvmpipe caps an invocation at 65535 loop iterations).
    let end = min(area, pass_.nb);
    for (var j = pass_.shift; j < end; j++) {
        let o = offsets[k] + j;
        tile_keys[o] = (y0 + j / rw) * cam.tiles_x + x0 + j % rw;
        tile_vals[o] = gid;
    }
}
