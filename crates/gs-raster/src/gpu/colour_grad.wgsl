// A colour gradient kept on the device (∂L/∂colour, three values a pixel) added into each
// pixel's record of a band: the twin of the colour part of `pixel::pixel_grads`, which the
// host's fold then leaves out. `add_colour` (one variant per record type) adds it to the colour
// channels and takes background · gradient from the final transmittance's coefficient. The
// records hold the host's fold of the other gradients, or zeros.

@compute @workgroup_size(256)
fn colour_grad_add(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n) {
        return;
    }
    add_colour(i, vec3<f32>(colour_grad[3u * i], colour_grad[3u * i + 1u], colour_grad[3u * i + 2u]));
}
