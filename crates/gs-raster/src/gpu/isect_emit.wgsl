// Writes the (tile, emission index) pairs of each depth-sorted Gaussian at its scanned offset,
// so that a stable sort by tile keeps every tile list in (depth, index) order, and the Gaussian
// of each emission index. A Gaussian's intersections are the contiguous emission indices
// [offsets[k], offsets[k + 1]) in row-major tile order: the fixed order in which `grad_reduce`
// sums its per-intersection gradients.

@compute @workgroup_size(256)
fn isect_emit(ids: Ids) {
    let k = thread_1d(ids);
    if (k >= pass_.n || keys[k] == INVISIBLE) {
        return;
    }
    let gid = vals[k];
    let r = proj[gid];
    let x0 = r.x0;
    let y0 = r.y0;
    let rw = r.x1 - x0;
    let area = rw * (r.y1 - y0);
    // Rectangle entries [pass_.shift, pass_.nb) in row-major order (one dispatch per window
    // of 32768 entries: llvmpipe caps an invocation at 65535 loop iterations).
    let end = min(area, pass_.nb);
    for (var j = pass_.shift; j < end; j++) {
        let o = offsets[k] + j;
        // A render that sized its buffers by a guess finds out at readback that it was short.
        if (o >= min(arrayLength(&tile_keys), min(arrayLength(&tile_vals), arrayLength(&isect_gid)))) {
            break;
        }
        tile_keys[o] = (y0 + j / rw) * cam.tiles_x + x0 + j % rw;
        tile_vals[o] = o;
        isect_gid[o] = gid;
    }
}
