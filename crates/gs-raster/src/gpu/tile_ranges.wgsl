// [start, end) of every tile's list in the tile-sorted intersections (ranges cleared to 0).

@group(0) @binding(2) var<storage, read> tile_keys: array<u32>;
@group(0) @binding(3) var<storage, read_write> ranges: array<u32>;

@compute @workgroup_size(256)
fn tile_ranges(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
               @builtin(local_invocation_index) li: u32) {
    let i = linear_group(wid, nwg) * 256u + li;
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
