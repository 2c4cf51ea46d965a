// After the tile sort (values = emission indices): the Gaussian of every tile-list position
// (what the blends read) and the tile-list position of every emission index (where
// `grad_reduce` finds the partial gradient that `raster_bwd` wrote for that intersection), for
// the first counters[2] positions (the intersections; padding follows them).

@compute @workgroup_size(256)
fn isect_link(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= min(pass_.n, counters[2])) {
        return;
    }
    let e = eidx[i];
    gids[i] = isect_gid[e];
    isect_pos[e] = i;
}
