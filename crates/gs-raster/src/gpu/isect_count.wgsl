// Tile intersections per depth-sorted Gaussian (0 for culled ones, which sort last), and the
// exact 64-bit total in counters[2] (low) / counters[3] (high).

@compute @workgroup_size(256)
fn isect_count(ids: Ids) {
    let k = thread_1d(ids);
    if (k >= pass_.n) {
        return;
    }
    if (keys[k] == INVISIBLE) {
        counts[k] = 0u;
        return;
    }
    let r = proj[vals[k]];
    let area = (r.x1 - r.x0) * (r.y1 - r.y0);
    counts[k] = area;
    let old = atomicAdd(&counters[2], area);
    if (old + area < old) {
        atomicAdd(&counters[3], 1u);
    }
}
