// [start, end) of every tile's list in the tile-sorted intersections (ranges cleared to 0).

@compute @workgroup_size(256)
fn tile_ranges(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n) {
        return;
    }
    let tile = tile_keys[i];
    if (i == 0u || tile_keys[i - 1u] != tile) {
        ranges[2u * tile] = i;
    }
    if (i + 1u == pass_.n || tile_keys[i + 1u] != tile) {
        ranges[2u * tile + 1u] = i + 1u;
    }
}
