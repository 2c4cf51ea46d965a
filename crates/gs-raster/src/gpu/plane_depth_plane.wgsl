// The band's plane depth into `depth` (see plane_depth.wgsl).

@compute @workgroup_size(256)
fn plane_depth_plane(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n) {
        return;
    }
    depth[i] = band_plane_depth(i);
}
