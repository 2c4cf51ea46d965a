// The normal terms' gradients kept on the device (∂L/∂Ñ, three values a pixel, and ∂L/∂z, one)
// added into each pixel's `PixelGrad` of a band: the twin of the normal and plane-depth parts of
// `pixel::pixel_grads`, which the host's fold then leaves out. The plane depth's gradient
// folds into Ñ and D through z = D / den, den = −Ñ·r + ε (∂z/∂D = 1/den, ∂z/∂Ñ = D·r/den²),
// with the band's accumulators (plane depth.wgsl's `acc`) as the render made them.

@compute @workgroup_size(256)
fn geometry_grad_add(ids: Ids) {
    let i = thread_1d(ids);
    let npix = pass_.n;
    if (i >= npix) {
        return;
    }
    var r = pixgrad[i];
    for (var c = 0u; c < 3u; c++) {
        r.channels[3u + c] += normal_grad[3u * i + c];
    }
    let gz = depth_grad[i];
    let ray = band_ray(i);
    let den = band_den(i, ray);
    if (den_ok(den)) {
        r.channels[6] += gz / den;
        let k = gz * acc[6u * npix + i] / (den * den);
        for (var c = 0u; c < 3u; c++) {
            r.channels[3u + c] += k * ray[c];
        }
    }
    pixgrad[i] = r;
}
