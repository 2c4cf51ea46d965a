// Plane depth of each pixel of a band from its blended Ñ and D, the twin of
// `pixel::plane_depth_at` (0 where the denominator is at or below the guard): a render that
// asks for plane depth without the normal or the distance reads back this one plane instead
// of the four it is made of. `acc` is the band's accumulators (plane c at c · pass_.n), `depth`
// the band's plane; pass_.base is the band's first pixel.

@compute @workgroup_size(256)
fn plane_depth_plane(ids: Ids) {
    let i = thread_1d(ids);
    let npix = pass_.n;
    if (i >= npix) {
        return;
    }
    let gp = pass_.base + i;
    let rx = ((f32(gp % cam.width) + 0.5) - cam.cx) / cam.fx;
    let ry = ((f32(gp / cam.width) + 0.5) - cam.cy) / cam.fy;
    let den = -(acc[3u * npix + i] * rx + acc[4u * npix + i] * ry + acc[5u * npix + i] * 1.0) + PLANE_DEPTH_EPS;
    var z = 0.0;
    if (den > cam.min_den && is_finite(den)) {
        z = acc[6u * npix + i] / den;
    }
    depth[i] = z;
}
