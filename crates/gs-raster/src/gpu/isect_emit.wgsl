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
    var o = offsets[k];
    for (var ty = proj[r + 1u]; ty < proj[r + 3u]; ty++) {
        for (var tx = proj[r]; tx < proj[r + 2u]; tx++) {
            tile_keys[o] = ty * cam.tiles_x + tx;
            tile_vals[o] = gid;
            o += 1u;
        }
    }
}
