// Plane depth of each pixel of a band from its blended Ñ and D, the twin of
// `pixel::plane_depth_at` (0 where the denominator is at or below the guard): a render that
// asks for plane depth without the normal or the distance reads back this one plane instead
// of the four it is made of (`plane_depth_plane`), and a render whose surface stays on the
// device writes it into its `SurfaceTexel`s (`surface_out.wgsl`). `acc` is the band's
// accumulators (plane c at c · pass_.n); pass_.base is the band's first pixel.

// The pixel ray K⁻¹(u, v, 1) of band pixel i (the host's `pixel::pixel_ray`).
fn band_ray(i: u32) -> vec3<f32> {
    let gp = pass_.base + i;
    return vec3<f32>(((f32(gp % cam.width) + 0.5) - cam.cx) / cam.fx, ((f32(gp / cam.width) + 0.5) - cam.cy) / cam.fy, 1.0);
}

// The plane-depth denominator −Ñ·r + ε of band pixel i with ray r.
fn band_den(i: u32, r: vec3<f32>) -> f32 {
    let npix = pass_.n;
    return -(acc[3u * npix + i] * r.x + acc[4u * npix + i] * r.y + acc[5u * npix + i] * r.z) + PLANE_DEPTH_EPS;
}

// Whether a denominator passes the guard.
fn den_ok(den: f32) -> bool {
    return den > cam.min_den && is_finite(den);
}

// The plane depth of band pixel i.
fn band_plane_depth(i: u32) -> f32 {
    let den = band_den(i, band_ray(i));
    var z = 0.0;
    if (den_ok(den)) {
        z = acc[6u * pass_.n + i] / den;
    }
    return z;
}
