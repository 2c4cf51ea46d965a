// A loss's gradient of the rendered plane kept on the device (∂L/∂Ñ and ∂L/∂D per pixel as
// `PlaneGrad` records, L_p's) added, times its weight (pass_.p1 as f32 bits), into each pixel's
// `PixelGrad` of a band: the twin of the normal and distance parts of `pixel::pixel_grads` for
// that loss, which the host's fold then leaves out.

@compute @workgroup_size(256)
fn plane_grad_add(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n) {
        return;
    }
    let w = bitcast<f32>(pass_.p1);
    let g = plane_grad[i];
    var r = pixgrad[i];
    for (var c = 0u; c < 3u; c++) {
        r.channels[3u + c] += w * g.n[c];
    }
    r.channels[6] += w * g.d;
    pixgrad[i] = r;
}
