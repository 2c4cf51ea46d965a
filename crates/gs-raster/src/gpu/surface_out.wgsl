// The rendered surface of each pixel of a band into a device image of `SurfaceTexel`s (plane
// depth z, Ñ, D, A = 1 − T_final), for a render whose surface stays on the device
// (RenderRequest::surface_on_device) so that the normal terms and L_p read it there: the twins
// of the host's plane depth (plane_depth.wgsl), normal, distance and alpha images. pass_.mode = 1: nothing was
// blended (no intersections) and the buffers hold no render: zeros, as the host assembles.

@compute @workgroup_size(256)
fn surface_out(ids: Ids) {
    let i = thread_1d(ids);
    let npix = pass_.n;
    if (i >= npix) {
        return;
    }
    var t: SurfaceTexel;
    if (pass_.mode == 0u) {
        t.z = band_plane_depth(i);
        for (var c = 0u; c < 3u; c++) {
            t.normal[c] = acc[(3u + c) * npix + i];
        }
        t.distance = acc[6u * npix + i];
        t.alpha = 1.0 - final_t[i];
    }
    surface[i] = t;
}
