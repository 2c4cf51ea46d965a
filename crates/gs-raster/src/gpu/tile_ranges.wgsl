// [start, end) of every tile's list in the tile-sorted intersections (ranges cleared to 0).
// The intersections are the first counters[2] of the pass_.n sorted (a render that sized its
// buffers by a guess sorts padding after them: `pad_keys`).

@compute @workgroup_size(256)
fn tile_ranges(ids: Ids) {
    let i = thread_1d(ids);
    let total = min(pass_.n, counters[2]);
    if (i >= total) {
        return;
    }
    let tile = tile_keys[i];
    if (i == 0u || tile_keys[i - 1u] != tile) {
        ranges[2u * tile] = i;
    }
    if (i + 1u == total || tile_keys[i + 1u] != tile) {
        ranges[2u * tile + 1u] = i + 1u;
    }
}

// Before the tile sort of a render whose buffers hold pass_.n ≥ counters[2] entries: the keys
// after the emitted ones sort last (all ones in every sorted digit; the sort is stable, so
// after a real key equal in its sorted bits too).
@compute @workgroup_size(256)
fn pad_keys(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n || i < counters[2]) {
        return;
    }
    tile_keys[i] = 0xFFFFFFFFu;
}
